// Scoring of answers against a run's ground truth (../shared/data/README.md): an answer with
// reference != -1 is a claim; a claim is a true positive when its (frame, reference) pair is
// listed, a false positive otherwise; recall = true positives / revisit frames, precision =
// TP / (TP + FP). The score threshold is swept over the distinct claim scores, high to low; claims
// with equal scores enter together.
#pragma once

#include <vector>

#include <nlohmann/json.hpp>

#include "common/eval/answers.h"
#include "common/eval/run.h"

namespace placerec {

struct PrPoint {
  double threshold = 0;  // the claims with score >= threshold count
  int true_positives = 0;
  int false_positives = 0;
  double precision = 1;
  double recall = 0;
};

struct RunScore {
  int frames = 0;
  int revisit_frames = 0;                 // distinct queries among the run's positives
  int answered_frames = 0;                // answers with reference != -1 (claims)
  double recall_at_100_precision = 0;     // best recall with no false positive (0 if none)
  double threshold_at_100_precision = 0;  // its threshold; 0 when there is none
  double max_f1 = 0;                      // the highest-threshold point wins ties
  double threshold_at_max_f1 = 0;
  double precision_at_max_f1 = 0;
  double recall_at_max_f1 = 0;
  // Sum over the sweep of (R_i - R_{i-1}) * P_i with R_0 = 0: step-wise, like sklearn's
  // average_precision_score, and the area under the curve WritePrCurvePng draws.
  double average_precision = 0;
  std::vector<PrPoint> curve;  // one point per distinct claim score, decreasing threshold
};

// Answers for frames outside the run, two answers for one frame, a reference below -1 or a NaN
// score are InvalidArgument; frames without an answer count as no claim. A claim whose reference
// is not an earlier frame of the run is simply a false positive. Revisit frames are counted from
// run.positives, so a hand-built Run needs only frames, name and positives.
StatusOr<RunScore> ScoreAnswers(const Run& run, const std::vector<Answer>& answers);

// The head of a run's summary.json, shared by placerec-eval and placerec-client: dataset, run,
// frames fed, revisit and answered frames, recall at 100 % precision, max F1 (with thresholds,
// precision and recall there) and average precision.
nlohmann::json ScoreSummary(const Run& run, int frames, const RunScore& score);

// The loop-closure decision's own precision and recall: true and false positives among the
// answers that claimed a loop closure.
nlohmann::json DecisionSummary(int true_positives, int false_positives, int revisit_frames);

}  // namespace placerec
