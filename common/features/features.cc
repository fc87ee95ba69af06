#include "common/features/features.h"

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "common/util/logging.h"

namespace placerec {

bool FeatureOptions::Check(std::string* error) const {
  if (max_features < 0) {
    *error = "sift max_features must be >= 0 (0 keeps all)";
    return false;
  }
  if (octave_layers < 1 || octave_layers > 10) {
    *error = "sift octave_layers must be in [1, 10]";
    return false;
  }
  if (contrast_threshold <= 0 || contrast_threshold >= 1) {
    *error = "sift contrast_threshold must be in (0, 1)";
    return false;
  }
  if (edge_threshold <= 1) {
    *error = "sift edge_threshold must be > 1";
    return false;
  }
  if (sigma <= 0) {
    *error = "sift sigma must be positive";
    return false;
  }
  if (min_keypoints_per_megapixel < 0) {
    *error = "sift min_keypoints_per_megapixel must be >= 0 (0 never retries)";
    return false;
  }
  if (low_contrast_threshold <= 0 || low_contrast_threshold >= 1) {
    *error = "sift low_contrast_threshold must be in (0, 1)";
    return false;
  }
  return true;
}

Features ExtractFeatures(const cv::Mat& image, const FeatureOptions& options) {
  CHECK(image.type() == CV_8UC3 || image.type() == CV_8UC1) << "expected an 8-bit image";
  cv::Mat gray;
  if (image.channels() == 3) {
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  } else {
    gray = image;
  }
  auto run = [&](double contrast_threshold) {
    cv::Ptr<cv::SIFT> sift =
        cv::SIFT::create(options.max_features, options.octave_layers, contrast_threshold,
                         options.edge_threshold, options.sigma, CV_8U);
    Features features;
    sift->detectAndCompute(gray, cv::noArray(), features.keypoints, features.descriptors);
    return features;
  };
  Features features = run(options.contrast_threshold);
  const double megapixels = static_cast<double>(gray.total()) * 1e-6;
  if (features.size() < options.min_keypoints_per_megapixel * megapixels &&
      options.low_contrast_threshold < options.contrast_threshold) {
    features = run(options.low_contrast_threshold);
  }
  if (features.descriptors.empty()) {
    features.descriptors.create(0, kDescriptorSize, CV_8U);
  }
  CHECK_EQ(features.descriptors.rows, features.size());
  return features;
}

}  // namespace placerec
