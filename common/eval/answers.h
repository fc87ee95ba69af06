// answers.csv: the one format every placerec tool writes for a run and every scorer reads.
//   frame,reference,score
// one row per frame in frame order; reference is the earlier frame the system claims this
// frame revisits (its best one), -1 when it claims none; score is larger for stronger claims.
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

Status WriteAnswers(const std::string& path, const std::vector<Answer>& answers);
StatusOr<std::vector<Answer>> ReadAnswers(const std::string& path);

}  // namespace placerec
