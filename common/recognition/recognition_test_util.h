// Test helpers shared by the recognition module's tests: random SIFT-like descriptors, noisy
// second views of them, and stored landmarks built from them. Fixed seeds come from the caller.
#pragma once

#include <cstdint>
#include <random>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "common/recognition/types.h"

namespace placerec {
namespace recognition_test {

// Random "descriptors": rows of uniform bytes, far apart from each other in 128 dimensions.
inline cv::Mat RandomDescriptors(int rows, std::mt19937* rng) {
  cv::Mat d(rows, 128, CV_8U);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < 128; ++c) d.at<uint8_t>(r, c) = static_cast<uint8_t>(byte(*rng));
  }
  return d;
}

// The same rows with a little noise, as a second view of the same object would give.
inline cv::Mat Noisy(const cv::Mat& d, std::mt19937* rng, int amplitude = 6) {
  cv::Mat out = d.clone();
  std::uniform_int_distribution<int> noise(-amplitude, amplitude);
  for (int r = 0; r < d.rows; ++r) {
    for (int c = 0; c < 128; ++c) {
      out.at<uint8_t>(r, c) = cv::saturate_cast<uint8_t>(d.at<uint8_t>(r, c) + noise(*rng));
    }
  }
  return out;
}

// A stored landmark with one keypoint per descriptor row, laid out on a small grid.
inline Landmark MakeLandmark(int64_t id, int64_t place, const cv::Mat& descriptors, int sift_count,
                             std::vector<float> peaks = {}) {
  Landmark landmark;
  landmark.id = LandmarkId(id);
  landmark.place = PlaceId(place);
  landmark.descriptors = descriptors;
  landmark.sift_count = sift_count;
  landmark.colour.peaks = std::move(peaks);
  for (int r = 0; r < descriptors.rows; ++r) {
    landmark.keypoints.emplace_back(cv::Point2f(10.0f * r, 5.0f * (r % 7)), 3.0f);
  }
  return landmark;
}

}  // namespace recognition_test
}  // namespace placerec
