// Pipeline step 6 (DESIGN.md; seed §5.2, §5.4-5.6, §5.7 step 3): every segment with more than
// 8 SIFT keypoints is a salient object, described by its SIFT descriptors, its SIFT count (the
// texture index, seed §5.5) and the dominant peaks of its colour-invariant H histogram (§5.6).
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "common/features/features.h"
#include "common/image/image.h"
#include "common/segmentation/segmentation.h"

namespace placerec {

struct ColourSignatureOptions {
  // Histogram of H over [-max_abs_h, max_abs_h] (ColourInvariantOptions::max_abs_h) in bins of
  // this width.
  double bin_width = 0.05;
  // A local peak counts as dominant when it is at least this fraction of the highest peak
  // (seed §5.6: 80 %).
  double peak_fraction = 0.8;
  // Two dominant peaks closer than this are one colour (the seed's colour tolerance, §5.6).
  double min_peak_separation = 0.2;
  // Fewer usable pixels than this and the object has no colour signature (it then passes every
  // colour filter).
  int min_pixels = 20;

  bool Check(std::string* error) const;
};

// Dominant H values of an object, highest peak first (seed §5.6). Empty when unknown.
struct ColourSignature {
  std::vector<float> peaks;

  bool known() const { return !peaks.empty(); }
  bool multi_peak() const { return peaks.size() > 1; }
};

// Dominant peaks of an H histogram with bins of `bin_width` starting at `min_h`.
ColourSignature FindDominantPeaks(const std::vector<float>& histogram, double min_h,
                                  const ColourSignatureOptions& options);

struct ObjectOptions {
  // A segment is an object when it holds more than 8 SIFT keypoints (seed §5.7 step 3).
  int min_keypoints = 9;
  // Background segments (sky, road, tree, grass, water) are objects too when set; by default
  // only structured segments are (seed §3.7).
  bool include_background = false;
  ColourSignatureOptions colour;

  bool Check(std::string* error) const;
};

struct SceneObject {
  int segment = -1;  // id in the SceneSegmentation
  SegmentClass segment_class = SegmentClass::kStructured;
  cv::Rect box;                    // full-resolution pixels
  cv::Rect working_box;            // the same box at the segmentation's working resolution
  cv::Mat mask;                    // CV_8U, 255 inside; working resolution, working_box size
  std::vector<int> keypoints;      // indices into the frame's Features
  cv::Mat descriptors;             // CV_8U, rows in the order of `keypoints`
  std::vector<float> h_histogram;  // normalised H histogram (sums to 1, or all 0)
  ColourSignature colour;

  int sift_count() const { return static_cast<int>(keypoints.size()); }
};

// Objects of one frame. `h` and `h_valid` are the colour invariant and its validity mask at the
// segmentation's working resolution (ColourInvariantH of the working image); `max_abs_h` is the
// clamp they were computed with.
std::vector<SceneObject> ExtractObjects(const Features& features,
                                        const SceneSegmentation& segmentation, const cv::Mat& h,
                                        const cv::Mat& h_valid, double max_abs_h,
                                        const ObjectOptions& options);

}  // namespace placerec
