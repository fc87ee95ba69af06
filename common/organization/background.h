// Background identification (DESIGN.md step 4; seed §3.4, §6.2.2 Table 6.4): five binary Gentle
// AdaBoost classifiers [Friedman00] (OpenCV ml::Boost) on the region appearance (textons.h: the
// seed's 151 numbers, by default plus 40 filter-bank means and deviations) decide whether a
// region is sky, tree, road, grass or water. A region none of them
// claims is "structured": a part of an object, which Perceptual Organization then groups.
//
// Files (one directory, normally models/): background.yml (format version, class order, the
// decision threshold) and background_<class>.yml.gz (one ml::Boost each).
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/ml.hpp>

#include "common/organization/boosted_forest.h"
#include "common/segmentation/segmentation.h"
#include "common/util/status.h"

namespace placerec {

constexpr int kBackgroundClasses = 5;
// The classes in classifier order: sky, tree, road, grass, water (their SegmentClass values are
// 0..4, so classifier c decides SegmentClass c).
SegmentClass BackgroundClassOf(int index);

struct BackgroundTrainingOptions {
  int weak_count = 150;  // boosted trees per classifier
  // Depth of each tree of the binary AdaBoost classifiers (seed §3.4). 3 rather than 2: slightly
  // better on held-out stanford_background training images, at about twice the boosting time
  // (docs/experiments/2026-11-22-segmentation-defaults.md).
  int max_depth = 3;
  double weight_trim_rate = 0.95;  // OpenCV Boost: samples outside this weight mass skip a round
  // Each classifier sees all its positive regions and at most this many negatives per positive
  // (drawn at random with `seed`); 0 keeps every negative.
  double max_negatives_per_positive = 4.0;
  uint64_t seed = 2009;

  bool Check(std::string* error) const;
};

// What training measured, per classifier on its own training samples.
// Index c < kBackgroundClasses: background class c; kBackgroundClasses + j: structured class j.
struct BackgroundTrainingSummary {
  std::vector<int> positives;
  std::vector<int> negatives;
  std::vector<double> training_accuracy;  // binary, on the samples it saw
  double seconds = 0.0;
};

// The Gentle AdaBoost both learned classifiers of this module use (background classes here,
// region merging in region_merging.h): OpenCV ml::Boost on the rows of `samples` (CV_32F) with
// 0/1 `responses` (CV_32S column) and initial per-row `weights` (CV_32F column), no surrogates,
// no cross-validation.
cv::Ptr<cv::ml::Boost> TrainGentleBoost(const cv::Mat& samples, const cv::Mat& responses,
                                        const cv::Mat& weights, int weak_count, int max_depth,
                                        double weight_trim_rate);
// Checks TrainGentleBoost's parameters: weak_count >= 1, max_depth in [1,
// BoostedForest::kMaxTrainingDepth], weight_trim_rate in [0, 1]. `what` names the classifier in
// the message ("background", "object classifier").
bool CheckGentleBoostOptions(const std::string& what, int weak_count, int max_depth,
                             double weight_trim_rate, std::string* error);
// The boosted sum of the weak responses for every row (> 0: the positive class), n x 1 CV_32F.
cv::Mat BoostedSums(const cv::ml::Boost& boost, const cv::Mat& samples);

class BackgroundClassifier {
 public:
  // 1: the five background classes; 2 adds the structured classes (reads 1).
  static constexpr int kFormatVersion = 2;

  BackgroundClassifier() = default;

  // Trains the five classifiers on `features` (n x d CV_32F, one region per row) with `labels`
  // (n values: a SegmentClass value 0..4 for background, 7 (or any other non-negative value)
  // for everything else, -1 to leave the row out) and optional per-row `weights` (the boosting's
  // initial sample weights; empty: all equal). When `structured_names` is not empty, one more
  // classifier per name learns the rows whose `structured_labels` value is its index (other
  // rows with a label >= 0 are its negatives). Classifiers train two at a time; the result is
  // deterministic for the same input. A class without rows of its own, or with every labelled
  // row, is InvalidArgument naming it (its classifier would have nothing to separate).
  static StatusOr<BackgroundClassifier> Train(const cv::Mat& features,
                                              const std::vector<int>& labels,
                                              const std::vector<float>& weights,
                                              const BackgroundTrainingOptions& options,
                                              BackgroundTrainingSummary* summary,
                                              const std::vector<std::string>& structured_names = {},
                                              const std::vector<int>& structured_labels = {});

  static StatusOr<BackgroundClassifier> Load(const std::string& directory);
  Status Save(const std::string& directory) const;

  bool empty() const { return !boosts_[0]; }
  int feature_size() const;

  // Raw boosted scores (sum of the weak responses, ml::Boost with RAW_OUTPUT | PREDICT_SUM;
  // > 0 means "this class"): n x 5 CV_32F. `features` may have more columns than the
  // classifiers were trained on (RegionAppearance's extras); they read the leading ones.
  cv::Mat Scores(const cv::Mat& features) const;
  // The structured classes' scores, n x structured_classes() CV_32F (n x 0 without them).
  cv::Mat StructuredScores(const cv::Mat& features) const;
  // Both for one row of at least feature_size() values, without a matrix (region merging
  // classifies every merged region): kBackgroundClasses scores into `background`,
  // structured_classes() into `structured`.
  void RowScores(const float* features, float* background, float* structured) const;
  int structured_classes() const { return static_cast<int>(structured_.size()); }
  const std::vector<std::string>& structured_names() const { return structured_names_; }
  // Per row: the class with the highest score when that score exceeds `threshold` (and, with
  // `one_per_class` and structured classifiers, every structured class's score), otherwise
  // kStructured.
  std::vector<SegmentClass> Classify(const cv::Mat& features, double threshold = 0.0,
                                     bool one_per_class = false) const;
  // The decision on one row of Scores: the best background class when its score exceeds
  // `threshold` and `rival` (the row's Rivals value), else kStructured.
  static SegmentClass Decide(const float* scores, double threshold,
                             float rival = -std::numeric_limits<float>::infinity());
  // Per row, what a background class must beat besides the threshold: the best structured
  // class's score under `one_per_class`, -infinity otherwise (and without structured
  // classifiers).
  std::vector<float> Rivals(const cv::Mat& features, bool one_per_class) const;

 private:
  // Rebuilds forests_ from boosts_ and structured_ (after training and loading).
  void Flatten();
  // The scores of `forests_[first, first + count)` on every row, n x count CV_32F; each
  // classifier reads the leading columns it was trained on (the seed's k + 1, or all of
  // RegionAppearance's).
  cv::Mat ForestScores(const cv::Mat& features, int first, int count) const;
  // The same for one row: `count` sums into `out`.
  void ForestSums(const float* row, int first, int count, float* out) const;

  std::array<cv::Ptr<cv::ml::Boost>, kBackgroundClasses> boosts_;
  std::vector<std::string> structured_names_;
  std::vector<cv::Ptr<cv::ml::Boost>> structured_;
  // What Scores and StructuredScores evaluate: the five background classifiers, then the
  // structured ones, flattened (boosted_forest.h; the same sums, without OpenCV's per-call cost
  // on the single rows region merging classifies after every merge).
  std::vector<BoostedForest> forests_;
};

}  // namespace placerec
