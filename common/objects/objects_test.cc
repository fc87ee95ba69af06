#include "common/objects/objects.h"

#include <gtest/gtest.h>

namespace placerec {
namespace {

// Features with `n` keypoints at the given full-resolution points; descriptor row i is filled
// with the value i so that copies can be checked.
Features MakeFeatures(const std::vector<cv::Point2f>& points) {
  Features features;
  features.descriptors.create(static_cast<int>(points.size()), kDescriptorSize, CV_8U);
  for (size_t i = 0; i < points.size(); ++i) {
    features.keypoints.emplace_back(points[i], 2.0f);
    features.descriptors.row(static_cast<int>(i)).setTo(static_cast<int>(i));
  }
  return features;
}

// A 40x20 working image (scale 0.5 of an 80x40 frame): segment 0 on the left half, segment 1
// on the right half.
SceneSegmentation TwoHalves(SegmentClass right_class) {
  SceneSegmentation segmentation;
  segmentation.labels = cv::Mat(20, 40, CV_32S, cv::Scalar(0));
  segmentation.labels(cv::Rect(20, 0, 20, 20)).setTo(1);
  segmentation.classes = {SegmentClass::kStructured, right_class};
  segmentation.scale = 0.5;
  return segmentation;
}

TEST(ObjectOptionsTest, DefaultsPassAndBadValuesFail) {
  std::string error;
  EXPECT_TRUE(ObjectOptions().Check(&error)) << error;
  ObjectOptions bad;
  bad.min_keypoints = 0;
  EXPECT_FALSE(bad.Check(&error));
  bad = ObjectOptions();
  bad.colour.peak_fraction = 1.5;
  EXPECT_FALSE(bad.Check(&error));
}

TEST(ObjectsTest, SegmentsWithMoreThanEightKeypointsBecomeObjects) {
  std::vector<cv::Point2f> points;
  for (int i = 0; i < 9; ++i) points.emplace_back(4.0f + 2 * i, 10.0f);   // left: 9 keypoints
  for (int i = 0; i < 8; ++i) points.emplace_back(44.0f + 2 * i, 10.0f);  // right: 8 keypoints
  const Features features = MakeFeatures(points);
  const SceneSegmentation segmentation = TwoHalves(SegmentClass::kStructured);
  const cv::Mat h(20, 40, CV_32F, cv::Scalar(0.5));
  const cv::Mat valid(20, 40, CV_8U, cv::Scalar(255));

  const std::vector<SceneObject> objects =
      ExtractObjects(features, segmentation, h, valid, 4.0, ObjectOptions());
  ASSERT_EQ(objects.size(), 1u);
  const SceneObject& object = objects[0];
  EXPECT_EQ(object.segment, 0);
  EXPECT_EQ(object.sift_count(), 9);
  EXPECT_EQ(object.working_box, cv::Rect(0, 0, 20, 20));
  EXPECT_EQ(object.box, cv::Rect(0, 0, 40, 40));
  EXPECT_EQ(object.mask.size(), cv::Size(20, 20));
  EXPECT_EQ(cv::countNonZero(object.mask), 400);
  ASSERT_EQ(object.descriptors.rows, 9);
  for (int r = 0; r < 9; ++r) {
    EXPECT_EQ(object.descriptors.at<uint8_t>(r, 0), object.keypoints[r]);
  }
  // A flat H of 0.5 gives one peak at 0.5 (bin centre within half a bin).
  ASSERT_EQ(object.colour.peaks.size(), 1u);
  EXPECT_NEAR(object.colour.peaks[0], 0.5f, 0.05f);
  EXPECT_FALSE(object.colour.multi_peak());
  float total = 0;
  for (float v : object.h_histogram) total += v;
  EXPECT_NEAR(total, 1.0f, 1e-5f);
}

TEST(ObjectsTest, BackgroundSegmentsAreObjectsOnlyWhenAsked) {
  std::vector<cv::Point2f> points;
  for (int i = 0; i < 10; ++i) points.emplace_back(44.0f + 2 * i, 10.0f);  // right half only
  const Features features = MakeFeatures(points);
  const SceneSegmentation segmentation = TwoHalves(SegmentClass::kSky);
  const cv::Mat h(20, 40, CV_32F, cv::Scalar(0.0));
  const cv::Mat valid(20, 40, CV_8U, cv::Scalar(255));
  ObjectOptions options;
  EXPECT_TRUE(ExtractObjects(features, segmentation, h, valid, 4.0, options).empty());
  options.include_background = true;
  const std::vector<SceneObject> objects =
      ExtractObjects(features, segmentation, h, valid, 4.0, options);
  ASSERT_EQ(objects.size(), 1u);
  EXPECT_EQ(objects[0].segment_class, SegmentClass::kSky);
  EXPECT_EQ(objects[0].box, cv::Rect(40, 0, 40, 40));
}

TEST(ObjectsTest, TwoColoursGiveTwoPeaksAndTooFewPixelsNone) {
  std::vector<cv::Point2f> points;
  for (int i = 0; i < 10; ++i) points.emplace_back(4.0f + 2 * i, 10.0f);
  const Features features = MakeFeatures(points);
  const SceneSegmentation segmentation = TwoHalves(SegmentClass::kStructured);
  cv::Mat h(20, 40, CV_32F, cv::Scalar(-2.0));
  h(cv::Rect(0, 10, 40, 10)).setTo(0.9);  // left segment: half H = -2, half H = 0.9
  cv::Mat valid(20, 40, CV_8U, cv::Scalar(255));
  std::vector<SceneObject> objects =
      ExtractObjects(features, segmentation, h, valid, 4.0, ObjectOptions());
  ASSERT_EQ(objects.size(), 1u);
  ASSERT_TRUE(objects[0].colour.multi_peak());
  EXPECT_EQ(objects[0].colour.peaks.size(), 2u);

  valid.setTo(0);  // no usable colour: unknown signature
  objects = ExtractObjects(features, segmentation, h, valid, 4.0, ObjectOptions());
  ASSERT_EQ(objects.size(), 1u);
  EXPECT_FALSE(objects[0].colour.known());
}

TEST(DominantPeaksTest, PeaksWithinEightyPercentOfTheHighest) {
  ColourSignatureOptions options;
  options.bin_width = 0.1;
  // Bins centred at 0.05, 0.15, ...: peaks at bin 2 (10), bin 8 (9) and bin 14 (5).
  std::vector<float> histogram(20, 0.0f);
  histogram[2] = 10;
  histogram[8] = 9;
  histogram[14] = 5;
  const ColourSignature signature = FindDominantPeaks(histogram, 0.0, options);
  ASSERT_EQ(signature.peaks.size(), 2u);
  EXPECT_NEAR(signature.peaks[0], 0.25f, 1e-5f);  // highest first
  EXPECT_NEAR(signature.peaks[1], 0.85f, 1e-5f);
}

TEST(DominantPeaksTest, CloseAndFlatPeaksAreOne) {
  ColourSignatureOptions options;
  options.bin_width = 0.05;
  std::vector<float> histogram(40, 0.0f);
  histogram[10] = 10;
  histogram[13] = 10;  // 0.15 apart: closer than the 0.2 colour tolerance, one colour
  EXPECT_EQ(FindDominantPeaks(histogram, 0.0, options).peaks.size(), 1u);
  EXPECT_TRUE(FindDominantPeaks(std::vector<float>(10, 0.0f), 0.0, options).peaks.empty());
}

}  // namespace
}  // namespace placerec
