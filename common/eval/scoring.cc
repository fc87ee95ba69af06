#include "common/eval/scoring.h"

#include <algorithm>
#include <cmath>

namespace placerec {
namespace {

double F1(double precision, double recall) {
  return precision + recall > 0 ? 2 * precision * recall / (precision + recall) : 0.0;
}

}  // namespace

StatusOr<RunScore> ScoreAnswers(const Run& run, const std::vector<Answer>& answers) {
  const int num_frames = static_cast<int>(run.frames.size());

  // Validate, and keep the claims (answers that name a reference).
  std::vector<bool> answered(num_frames, false);
  std::vector<Answer> claims;
  for (const Answer& a : answers) {
    if (a.frame < 0 || a.frame >= num_frames) {
      return Status::InvalidArgument("answer for frame " + std::to_string(a.frame) + ", but run '" +
                                     run.name + "' has frames 0.." +
                                     std::to_string(num_frames - 1) +
                                     "; were the answers computed on another run?");
    }
    if (answered[a.frame]) {
      return Status::InvalidArgument("frame " + std::to_string(a.frame) +
                                     " has two answers; give one per frame (its best)");
    }
    answered[a.frame] = true;
    if (a.reference < -1) {
      return Status::InvalidArgument("answer for frame " + std::to_string(a.frame) +
                                     " has reference " + std::to_string(a.reference) +
                                     "; use -1 for no claim");
    }
    if (std::isnan(a.score)) {
      return Status::InvalidArgument("answer for frame " + std::to_string(a.frame) +
                                     " has a NaN score");
    }
    if (a.reference != -1) claims.push_back(a);
  }

  RunScore score;
  score.frames = num_frames;
  // Revisit frames straight from the positives (sorted by query), so that a hand-built Run
  // scores the same as a loaded one.
  int last_query = -1;
  for (const auto& [query, reference] : run.positives) {
    if (query != last_query) ++score.revisit_frames;
    last_query = query;
  }
  score.answered_frames = static_cast<int>(claims.size());

  // Strongest claims first; claims with equal scores enter the sweep together.
  std::stable_sort(claims.begin(), claims.end(),
                   [](const Answer& a, const Answer& b) { return a.score > b.score; });
  int tp = 0;
  int fp = 0;
  double previous_recall = 0;
  for (size_t i = 0; i < claims.size();) {
    const double threshold = claims[i].score;
    for (; i < claims.size() && claims[i].score == threshold; ++i) {
      // A reference outside the run or not earlier than the frame is simply not listed: an FP.
      if (run.IsPositive(claims[i].frame, claims[i].reference)) {
        ++tp;
      } else {
        ++fp;
      }
    }
    PrPoint point;
    point.threshold = threshold;
    point.true_positives = tp;
    point.false_positives = fp;
    point.precision = static_cast<double>(tp) / (tp + fp);
    point.recall = score.revisit_frames > 0 ? static_cast<double>(tp) / score.revisit_frames : 0;
    score.curve.push_back(point);

    if (fp == 0 && point.recall > score.recall_at_100_precision) {
      score.recall_at_100_precision = point.recall;
      score.threshold_at_100_precision = threshold;
    }
    const double f1 = F1(point.precision, point.recall);
    if (f1 > score.max_f1) {
      score.max_f1 = f1;
      score.threshold_at_max_f1 = threshold;
      score.precision_at_max_f1 = point.precision;
      score.recall_at_max_f1 = point.recall;
    }
    score.average_precision += (point.recall - previous_recall) * point.precision;
    previous_recall = point.recall;
  }
  return score;
}

nlohmann::json ScoreSummary(const Run& run, int frames, const RunScore& score) {
  return {{"dataset", run.dataset_dir},
          {"run", run.name},
          {"frames", frames},
          {"revisit_frames", score.revisit_frames},
          {"answered_frames", score.answered_frames},
          {"recall_at_100_precision", score.recall_at_100_precision},
          {"threshold_at_100_precision", score.threshold_at_100_precision},
          {"max_f1", score.max_f1},
          {"threshold_at_max_f1", score.threshold_at_max_f1},
          {"precision_at_max_f1", score.precision_at_max_f1},
          {"recall_at_max_f1", score.recall_at_max_f1},
          {"average_precision", score.average_precision}};
}

nlohmann::json DecisionSummary(int true_positives, int false_positives, int revisit_frames) {
  const int claims = true_positives + false_positives;
  return {
      {"true_positives", true_positives},
      {"false_positives", false_positives},
      {"precision", claims > 0 ? static_cast<double>(true_positives) / claims : 1.0},
      {"recall", revisit_frames > 0 ? static_cast<double>(true_positives) / revisit_frames : 0.0}};
}

}  // namespace placerec
