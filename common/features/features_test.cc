#include "common/features/features.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

namespace placerec {
namespace {

cv::Mat Checkerboard(int size, int cell) {
  cv::Mat image(size, size, CV_8UC3, cv::Scalar(255, 255, 255));
  for (int y = 0; y < size; y += cell) {
    for (int x = (y / cell % 2) * cell; x < size; x += 2 * cell) {
      cv::rectangle(image, cv::Rect(x, y, cell, cell), cv::Scalar(0, 0, 0), cv::FILLED);
    }
  }
  cv::circle(image, cv::Point(size / 3, size / 2), size / 8, cv::Scalar(0, 0, 255), cv::FILLED);
  return image;
}

TEST(FeaturesTest, DefaultsPassAndBadValuesFail) {
  std::string error;
  EXPECT_TRUE(FeatureOptions().Check(&error)) << error;
  FeatureOptions bad;
  bad.contrast_threshold = 0;
  EXPECT_FALSE(bad.Check(&error));
  bad = FeatureOptions();
  bad.max_features = -1;
  EXPECT_FALSE(bad.Check(&error));
}

TEST(FeaturesTest, TexturedImageGivesByteDescriptors) {
  const Features features = ExtractFeatures(Checkerboard(256, 32), FeatureOptions());
  ASSERT_GT(features.size(), 10);
  EXPECT_EQ(features.descriptors.type(), CV_8U);
  EXPECT_EQ(features.descriptors.cols, kDescriptorSize);
  EXPECT_EQ(features.descriptors.rows, features.size());
}

TEST(FeaturesTest, FlatImageGivesNoKeypointsButAValidMatrix) {
  const Features features =
      ExtractFeatures(cv::Mat(128, 128, CV_8UC3, cv::Scalar(90, 90, 90)), FeatureOptions());
  EXPECT_EQ(features.size(), 0);
  EXPECT_EQ(features.descriptors.cols, kDescriptorSize);
  EXPECT_EQ(features.descriptors.rows, 0);
}

TEST(FeaturesTest, PlainFramesRetryWithALowerContrastThreshold) {
  // A faint pattern: few keypoints at the default threshold, many more after the retry.
  cv::Mat faint = Checkerboard(256, 16);
  faint.convertTo(faint, -1, 0.04, 120);
  FeatureOptions once;
  once.min_keypoints_per_megapixel = 0;
  FeatureOptions adaptive;
  adaptive.min_keypoints_per_megapixel = 20000;
  const int without = ExtractFeatures(faint, once).size();
  const int with = ExtractFeatures(faint, adaptive).size();
  EXPECT_LT(without, 50);
  EXPECT_GT(with, 2 * without + 10);
}

TEST(FeaturesTest, MaxFeaturesCaps) {
  FeatureOptions options;
  options.max_features = 5;
  const Features all = ExtractFeatures(Checkerboard(256, 16), FeatureOptions());
  const Features capped = ExtractFeatures(Checkerboard(256, 16), options);
  ASSERT_GT(all.size(), 20);
  // cv::SIFT keeps keypoints tied with the last response at the cut, so allow a few more.
  EXPECT_GE(capped.size(), 5);
  EXPECT_LE(capped.size(), 10);
}

}  // namespace
}  // namespace placerec
