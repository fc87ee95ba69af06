// answers.csv: the one format every placerec tool writes for a run and every scorer reads.
//   frame,reference,score
// one row per frame in frame order; reference is the earlier frame the system claims this
// frame revisits (its best one), -1 when it claims none; score is larger for stronger claims.
// Scores are written as the shortest decimal text that reads back bit-exactly ("0.1", "1e-07"),
// independent of the C locale.
#pragma once

#include <string>
#include <vector>

#include "common/util/status.h"

namespace placerec {

struct Answer {
  int frame = 0;
  int reference = -1;
  double score = 0.0;
};

// Writes the answers in the order given. InvalidArgument (nothing written) for a negative frame,
// a reference that is neither -1 nor an earlier frame, or a NaN score; IoError when the file
// cannot be written.
Status WriteAnswers(const std::string& path, const std::vector<Answer>& answers);

// Reads and checks an answers file: the exact header, integer frame and reference, a numeric
// score, the same rules as WriteAnswers, and at most one row per frame. Errors name the file and
// line; NotFound when the file does not exist.
StatusOr<std::vector<Answer>> ReadAnswers(const std::string& path);

}  // namespace placerec
