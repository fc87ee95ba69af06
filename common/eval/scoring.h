// Scoring of answers against a run's ground truth (../shared/data/README.md): an answer is a
// true positive when its (frame, reference) pair is listed, a false positive otherwise; recall =
// true positives / revisit frames. The score threshold is swept over the distinct answer scores.
#pragma once

#include <vector>

#include "common/eval/answers.h"
#include "common/eval/run.h"

namespace placerec {

struct PrPoint {
  double threshold = 0;  // answers with score >= threshold are claims
  int true_positives = 0;
  int false_positives = 0;
  double precision = 1;
  double recall = 0;
};

struct RunScore {
  int frames = 0;
  int revisit_frames = 0;
  int answered_frames = 0;              // answers with reference != -1
  double recall_at_100_precision = 0;   // best recall with no false positive (0 if none)
  double threshold_at_100_precision = 0;
  double max_f1 = 0;
  double threshold_at_max_f1 = 0;
  double precision_at_max_f1 = 0;
  double recall_at_max_f1 = 0;
  double average_precision = 0;         // sum over thresholds of (R_i - R_{i-1}) * P_i
  std::vector<PrPoint> curve;           // one point per distinct score, decreasing threshold
};

// Answers for frames outside the run are an error; frames without an answer count as "none".
StatusOr<RunScore> ScoreAnswers(const Run& run, const std::vector<Answer>& answers);

}  // namespace placerec
