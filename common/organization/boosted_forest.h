// Fast prediction for the boosted classifiers of this module (OpenCV ml::Boost with ordered
// variables): the trees flattened into one array of nodes, walked without OpenCV's per-call
// overhead. The sum of a sample is exactly what ml::Boost::predict returns with RAW_OUTPUT |
// PREDICT_SUM (leaf values added in tree order in double precision), several times faster on
// the small batches the region merging scores after every merge.
#pragma once

#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/ml.hpp>

namespace placerec {

class BoostedForest {
 public:
  BoostedForest() = default;
  // Flattens a trained `boost` whose variables are all ordered (TrainGentleBoost trains so;
  // ml::Boost keeps no public record of variable types, so categorical splits cannot be told
  // apart and would be misread).
  explicit BoostedForest(const cv::ml::Boost& boost);

  int var_count() const { return var_count_; }
  // The boosted sum of one sample of at least var_count() values.
  double Sum(const float* sample) const;

 private:
  struct Node {
    int var = -1;  // -1: leaf
    float threshold = 0.0f;
    bool inversed = false;  // go right when value <= threshold
    int left = -1;
    int right = -1;
    double value = 0.0;  // the leaf's weak response
  };
  std::vector<Node> nodes_;
  std::vector<int> roots_;
  int var_count_ = 0;
};

}  // namespace placerec
