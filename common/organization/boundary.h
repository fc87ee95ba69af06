// Learned object boundaries: a Gentle AdaBoost classifier that tells, at a pixel on the boundary
// between two superpixels, whether an object boundary of the ground truth runs there or only an
// edge inside one object (a window frame, a shadow, a texture edge). It extends the contrast
// cues of the learned region merging (region_merging.h; seed §3.7) with what a pixel's
// neighbourhood shows in several directions and at several distances, learned from the
// annotation itself rather than from colour differences alone.
//
// Features of a pixel (kBoundaryFeatures numbers, computed from the filter bank of
// filter_bank.h on the working image; the layout is part of the model format):
//   for each of the 12 channels G1.L .. G4.b, LoG1, LoG2, LoG4 and each distance d in {1, 3, 6}
//   pixels, the largest and the smallest over four directions (horizontal, vertical, both
//   diagonals) of |f(p + d u) - f(p - d u)|                                         72
//   the colour difference (Delta E) across p in the four directions, largest and smallest, on
//   G1 at d = 1, G2 at d = 3 and G4 at d = 6                                          6
//   the 20 bank values at p                                                          20
//   the gradient magnitude of G2.L and of G4.L at p                                   2
//   p's height in the image (0 top, 1 bottom)                                         1
// Positions beyond the border are clamped to it.
//
// The model file (normally models/boundary.yml.gz) holds one OpenCV ml::Boost with a format
// version and the feature count; placerec-train boundary learns it.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/ml.hpp>

#include "common/organization/boosted_forest.h"
#include "common/util/status.h"

namespace placerec {

constexpr int kBoundaryFeatures = 101;

// Writes the kBoundaryFeatures features of pixel (x, y) of `bank` (ComputeFilterBank's
// CV_32FC(20) image) to `out`.
void BoundaryPixelFeatures(const cv::Mat& bank, int x, int y, float* out);

// CV_8U mask of the pixels of `labels` (CV_32S) that have a 4-neighbour with another label:
// the pixels on either side of every crack. With `ignore_unlabelled`, labels <= 0 (ground
// truth's unlabelled pixels) neither are nor make crack pixels.
cv::Mat CrackPixels(const cv::Mat& labels, bool ignore_unlabelled = false);

class BoundaryModel {
 public:
  static constexpr int kFormatVersion = 1;
  static constexpr const char* kFileName = "boundary.yml.gz";

  struct TrainingOptions {
    int weak_count = 100;
    int max_depth = 3;
    double weight_trim_rate = 0.95;
    bool Check(std::string* error) const;
  };

  BoundaryModel() = default;
  // `features` n x kBoundaryFeatures CV_32F, `labels` 1 (object boundary) / 0, `weights` per
  // row (empty: all alike).
  static BoundaryModel Train(const cv::Mat& features, const std::vector<int>& labels,
                             const std::vector<float>& weights, const TrainingOptions& options);
  // Loads DIR/boundary.yml.gz; NotFound when the file is missing.
  static StatusOr<BoundaryModel> Load(const std::string& directory);
  // Writes DIR/boundary.yml.gz (through a temporary file, so a failed write leaves the old one).
  Status Save(const std::string& directory) const;

  bool empty() const { return boost_.empty(); }
  // Boosted sum (> 0: object boundary) of one feature row.
  double Score(const float* features) const;
  // CV_32F map of the boosted sums at the pixels where `mask` (CV_8U, bank's size) is set; 0
  // elsewhere.
  cv::Mat ScoreMap(const cv::Mat& bank, const cv::Mat& mask) const;

 private:
  cv::Ptr<cv::ml::Boost> boost_;
  BoostedForest forest_;
};

}  // namespace placerec
