// Pipeline step 2 (DESIGN.md, seed §5.1): SIFT keypoints and descriptors on the whole frame,
// computed with OpenCV's cv::SIFT. Descriptors are 128 bytes (CV_8U), the form they are stored in.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace placerec {

// Bytes in one SIFT descriptor.
constexpr int kDescriptorSize = 128;

struct FeatureOptions {
  // Keep at most this many strongest keypoints; 0 keeps all (cv::SIFT nfeatures).
  int max_features = 0;
  // Scale-space layers per octave (Lowe 2004; cv::SIFT default).
  int octave_layers = 3;
  // DoG contrast threshold: lower finds more keypoints on low-texture scenes (cv::SIFT default).
  double contrast_threshold = 0.04;
  // Edge-response threshold (cv::SIFT default).
  double edge_threshold = 10.0;
  // Gaussian sigma of the first octave (cv::SIFT default).
  double sigma = 1.6;
  // Plain scenes (an indoor corridor) give few keypoints at the default contrast threshold:
  // when a frame has fewer than this many per megapixel (about 1,000 on a 960x540 frame, 600
  // on 640x480), SIFT runs again with low_contrast_threshold. 0 never retries.
  int min_keypoints_per_megapixel = 2000;
  double low_contrast_threshold = 0.01;

  bool Check(std::string* error) const;
};

struct Features {
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;  // CV_8U, one row of kDescriptorSize bytes per keypoint

  int size() const { return static_cast<int>(keypoints.size()); }
};

// SIFT on an 8-bit BGR or grey image. Thread-safe: each call uses its own detector.
Features ExtractFeatures(const cv::Mat& image, const FeatureOptions& options);

}  // namespace placerec
