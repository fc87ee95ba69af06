// Object classification (seed Ch. 4, §4.2 and §6.2.1): one binary Gentle AdaBoost classifier
// per object class [Friedman00], each on the features that the selection of
// feature_selection.h picked for its class, and the one-per-class decision [Guruswami99]: an
// object is given the class whose classifier is the most confident (highest boosted sum).
//
// Files (one directory): objects.yml (format version, description size, class names, each
// class's selected columns) and objects_<index>.yml.gz (one ml::Boost per class).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/ml.hpp>

#include "common/classification/feature_selection.h"
#include "common/util/status.h"

namespace placerec {

struct ObjectClassifierOptions {
  // The final classifier of each class: Gentle AdaBoost with this many trees of this depth
  // (seed §6.2: "GML AdaBoost"; its rounds for MSRC are not given).
  int weak_count = 100;
  int max_depth = 2;
  double weight_trim_rate = 0.95;
  // Seed §4.2 per class (true), or every column of the groups (false: "full set", Table 6.6).
  bool select_features = true;
  FeatureSelectionOptions selection;
  // Classes are trained this many at a time (each class is deterministic on its own).
  int threads = 2;

  bool Check(std::string* error) const;
};

// What training did per class.
struct ObjectClassSummary {
  std::string name;
  int positives = 0;
  int negatives = 0;
  FeatureSelectionSummary selection;  // empty without select_features
  std::vector<int> per_group;         // columns the classifier reads, per group
  double seconds = 0.0;
};

class ObjectClassifier {
 public:
  static constexpr int kFormatVersion = 1;

  ObjectClassifier() = default;

  // Trains one classifier per name on `samples` (n x d CV_32F descriptions) with `labels` (n
  // class indices into `names`; -1 leaves a row out): class c's positives are its rows, its
  // negatives every other labelled row, both weighing alike in total. Only the columns of
  // `groups` are read. `progress` (may be empty) is called after each class with the number
  // done. InvalidArgument for sizes that disagree, a label out of range or a class with fewer
  // positives than the selection's folds (named).
  static StatusOr<ObjectClassifier> Train(
      const cv::Mat& samples, const std::vector<int>& labels, const std::vector<std::string>& names,
      const std::vector<FeatureGroup>& groups, const ObjectClassifierOptions& options,
      std::vector<ObjectClassSummary>* summary = nullptr,
      const std::function<void(int done, const ObjectClassSummary&)>& progress = {});

  static StatusOr<ObjectClassifier> Load(const std::string& directory);
  Status Save(const std::string& directory) const;

  int classes() const { return static_cast<int>(names_.size()); }
  const std::vector<std::string>& names() const { return names_; }
  // The description length the classifiers read columns of.
  int feature_size() const { return feature_size_; }
  // Columns class c's classifier reads, increasing.
  const std::vector<int>& columns(int c) const { return columns_[c]; }

  // Boosted sums (> 0: the class), n x classes() CV_32F, for n x feature_size() CV_32F rows.
  cv::Mat Scores(const cv::Mat& samples) const;
  // One-per-class: per row the class of the highest score among those with `allowed[c]` (all
  // when empty).
  static std::vector<int> Decide(const cv::Mat& scores, const std::vector<bool>& allowed = {});

 private:
  int feature_size_ = 0;
  std::vector<std::string> names_;
  std::vector<std::vector<int>> columns_;
  std::vector<cv::Ptr<cv::ml::Boost>> boosts_;
};

}  // namespace placerec
