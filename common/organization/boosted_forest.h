// Fast prediction for the boosted classifiers of this module (OpenCV ml::Boost with ordered
// variables): each tree padded to a perfect binary tree of its own depth and stored in heap
// order, so that a sample walks it with one comparison per level and no data-dependent branch
// or pointer chase. The sum of a sample is exactly what ml::Boost::predict returns with
// RAW_OUTPUT | PREDICT_SUM (leaf values added in tree order in double precision), several times
// faster on the small batches the region merging scores after every merge and on the pixels
// the boundary classifier scores.
#pragma once

#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/ml.hpp>

namespace placerec {

class BoostedForest {
 public:
  // The deepest tree the layout takes (2^12 leaves); loaders refuse deeper models.
  static constexpr int kMaxDepth = 12;
  // The deepest trees the training commands grow (below kMaxDepth, so that what they write
  // always loads).
  static constexpr int kMaxTrainingDepth = 10;
  // The depth of the deepest tree of a trained `boost`.
  static int Depth(const cv::ml::Boost& boost);
  // Whether every leaf value and split threshold of `boost` is a finite number and every split
  // tests one of its getVarCount() variables. A damaged model file can hold NaN, which then wins
  // or loses every comparison, or a split on a variable past the last (OpenCV's reader lets the
  // one just past through), which reads past the sample: loaders refuse both.
  static bool Intact(const cv::ml::Boost& boost);

  BoostedForest() = default;
  // Flattens a trained `boost` whose variables are all ordered (TrainGentleBoost trains so;
  // ml::Boost keeps no public record of variable types, so categorical splits cannot be told
  // apart and would be misread) and whose trees are at most kMaxDepth deep.
  explicit BoostedForest(const cv::ml::Boost& boost);

  int var_count() const { return var_count_; }
  // The boosted sum of one sample of at least var_count() values.
  double Sum(const float* sample) const;
  // The sums of `n` samples, sample i at samples + i * stride, into out[0..n-1]: each equal to
  // Sum of that sample. Walks each tree for a batch of samples at once, so that the
  // independent walks overlap instead of each waiting for its own loads.
  void Sums(const float* samples, size_t stride, int n, double* out) const;

 private:
  struct Tree {
    int depth = 0;        // levels of splits (0: a single leaf)
    int first_split = 0;  // index into vars_ / thresholds_ of its 2^depth - 1 splits
    int first_leaf = 0;   // index into leaves_ of its 2^depth leaves
  };
  std::vector<Tree> trees_;
  // Split k of a tree sends a sample to child 2k + 2 when !(value <= threshold), else 2k + 1
  // (OpenCV's "inversed" splits have their children swapped; padding splits compare with
  // +infinity and lead to one leaf on both sides).
  std::vector<int> vars_;
  std::vector<float> thresholds_;
  std::vector<double> leaves_;
  int var_count_ = 0;
};

}  // namespace placerec
