// Test helpers shared by the pipeline module's tests: a synthetic street of textured buildings,
// views of it as a robot driving along would take them, and analyzer options that suit it.
#pragma once

#include <random>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "common/pipeline/frame_analyzer.h"

namespace placerec {
namespace pipeline_test {

// A synthetic street, 3200 x 240: sky, ground and 60 textured "buildings" of random colours,
// each sprinkled with darker and brighter spots so that SIFT finds keypoints inside them.
inline constexpr int kViewWidth = 320;
inline constexpr int kStep = 80;  // robots move a quarter view per frame

inline cv::Mat World(unsigned seed) {
  std::mt19937 rng(seed);
  cv::Mat world(240, 3200, CV_8UC3);
  world.rowRange(0, 100).setTo(cv::Scalar(230, 200, 150));
  world.rowRange(100, 240).setTo(cv::Scalar(90, 100, 100));
  std::uniform_int_distribution<int> colour(30, 230);
  std::uniform_int_distribution<int> x(0, 3150);
  std::uniform_int_distribution<int> width(40, 110);
  std::uniform_int_distribution<int> height(40, 130);
  std::uniform_int_distribution<int> shade(-60, 60);
  std::uniform_int_distribution<int> radius(1, 3);
  for (int i = 0; i < 60; ++i) {
    cv::Rect r(x(rng), 30 + colour(rng) / 4, width(rng), height(rng));
    r &= cv::Rect(0, 0, world.cols, world.rows);
    const cv::Scalar base(colour(rng), colour(rng), colour(rng));
    world(r).setTo(base);
    std::uniform_int_distribution<int> px(r.x, r.x + r.width - 1);
    std::uniform_int_distribution<int> py(r.y, r.y + r.height - 1);
    for (int k = 0; k < r.area() / 80; ++k) {
      cv::circle(world, cv::Point(px(rng), py(rng)), radius(rng),
                 base + cv::Scalar::all(shade(rng)), cv::FILLED);
    }
  }
  return world;
}

inline cv::Mat View(const cv::Mat& world, int x) {
  return world(cv::Rect(x, 0, kViewWidth, world.rows)).clone();
}

// The synthetic street is not a scene the background classifiers were trained on (flat sky and
// ground colours, rectangles touching each other), so these tests of the stages downstream of
// segmentation use superpixels as objects; Perceptual Organization is tested in
// common/organization and on real frames in tests/.
// The street is drawn at the 320 px the tests expect, so small-frame upscaling (tested on its
// own in frame_analyzer_test.cc) is off.
inline AnalyzerOptions SyntheticAnalyzerOptions() {
  AnalyzerOptions options;
  options.segmentation = SegmentationMethod::kSuperpixels;
  options.small_frame_width = 0;
  return options;
}

}  // namespace pipeline_test
}  // namespace placerec
