#include "common/segmentation/segmentation.h"

#include <cmath>
#include <string>

#include <gtest/gtest.h>

namespace placerec {
namespace {

TEST(SegmentClassTest, NamesAndBackground) {
  EXPECT_STREQ(SegmentClassName(SegmentClass::kSky), "sky");
  EXPECT_STREQ(SegmentClassName(SegmentClass::kTree), "tree");
  EXPECT_STREQ(SegmentClassName(SegmentClass::kRoad), "road");
  EXPECT_STREQ(SegmentClassName(SegmentClass::kGrass), "grass");
  EXPECT_STREQ(SegmentClassName(SegmentClass::kWater), "water");
  EXPECT_STREQ(SegmentClassName(SegmentClass::kStructured), "structured");
  EXPECT_STREQ(SegmentClassName(static_cast<SegmentClass>(5)), "unknown");
  for (SegmentClass c : {SegmentClass::kSky, SegmentClass::kTree, SegmentClass::kRoad,
                         SegmentClass::kGrass, SegmentClass::kWater}) {
    EXPECT_TRUE(IsBackground(c)) << SegmentClassName(c);
  }
  EXPECT_FALSE(IsBackground(SegmentClass::kStructured));
  EXPECT_FALSE(IsBackground(static_cast<SegmentClass>(5)));
  // Ids of stanford_background/classes.txt.
  EXPECT_EQ(static_cast<int>(SegmentClass::kWater), 4);
  EXPECT_EQ(static_cast<int>(SegmentClass::kStructured), 7);
}

TEST(SegmentClassTest, KnownValuesAreTheEnumerators) {
  for (int64_t value : {0, 1, 2, 3, 4, 7}) EXPECT_TRUE(IsKnownSegmentClass(value)) << value;
  for (int64_t value : {-1, 5, 6, 8, 255, 256 + 7})
    EXPECT_FALSE(IsKnownSegmentClass(value)) << value;
}

TEST(WorkingImageTest, ResizesToWorkingWidthWithScale) {
  const cv::Mat bgr(480, 640, CV_8UC3, cv::Scalar(255, 255, 255));
  const WorkingImage half = MakeWorkingImage(bgr, 320);
  EXPECT_EQ(half.bgr.cols, 320);
  EXPECT_EQ(half.bgr.rows, 240);
  EXPECT_EQ(half.bgr.type(), CV_8UC3);
  EXPECT_DOUBLE_EQ(half.scale, 0.5);
  ASSERT_EQ(half.lab.type(), CV_32FC3);
  EXPECT_EQ(half.lab.size(), half.bgr.size());
  // White is L = 100, a = b = 0.
  const cv::Vec3f white = half.lab.at<cv::Vec3f>(10, 10);
  EXPECT_NEAR(white[0], 100.0f, 0.01f);
  EXPECT_NEAR(white[1], 0.0f, 0.01f);
  EXPECT_NEAR(white[2], 0.0f, 0.01f);

  // Height rounds; the scale is the width ratio.
  const WorkingImage odd = MakeWorkingImage(cv::Mat(301, 1000, CV_8UC3, cv::Scalar(0, 0, 0)), 320);
  EXPECT_EQ(odd.bgr.cols, 320);
  EXPECT_EQ(odd.bgr.rows, 96);  // 301 * 0.32 = 96.32
  EXPECT_DOUBLE_EQ(odd.scale, 0.32);

  // Narrower than the working width, or working width 0: unchanged.
  for (int width : {0, 640, 1000}) {
    const WorkingImage same = MakeWorkingImage(bgr, width);
    EXPECT_EQ(same.bgr.size(), bgr.size()) << width;
    EXPECT_DOUBLE_EQ(same.scale, 1.0) << width;
  }
}

TEST(WorkingImageTest, AveragesWhenShrinking) {
  // 2x2 blocks average under INTER_AREA.
  cv::Mat bgr(2, 4, CV_8UC3, cv::Scalar(0, 0, 0));
  bgr.at<cv::Vec3b>(0, 0) = cv::Vec3b(200, 100, 40);
  const WorkingImage image = MakeWorkingImage(bgr, 2);
  ASSERT_EQ(image.bgr.size(), cv::Size(2, 1));
  EXPECT_EQ(image.bgr.at<cv::Vec3b>(0, 0), cv::Vec3b(50, 25, 10));
  EXPECT_EQ(image.bgr.at<cv::Vec3b>(0, 1), cv::Vec3b(0, 0, 0));
}

SceneSegmentation Grid4x3(double scale) {
  SceneSegmentation s;
  s.labels = (cv::Mat_<int>(3, 4) << 0, 1, 2, 3,  //
              4, 5, 6, 7,                         //
              8, 9, 10, 11);
  s.classes.assign(12, SegmentClass::kStructured);
  s.scale = scale;
  return s;
}

TEST(SceneSegmentationTest, SegmentAtMapsFullResolutionPoints) {
  // Full resolution 8x6, working 4x3: full pixels 2i and 2i+1 fall into working pixel i.
  const SceneSegmentation s = Grid4x3(0.5);
  EXPECT_EQ(s.size(), 12);
  EXPECT_EQ(s.SegmentAt(0.0f, 0.0f), 0);
  EXPECT_EQ(s.SegmentAt(1.0f, 1.0f), 0);
  EXPECT_EQ(s.SegmentAt(1.4f, 1.4f), 0);
  EXPECT_EQ(s.SegmentAt(1.6f, 0.0f), 1);  // (1.6 + 0.5) / 2 = 1.05
  EXPECT_EQ(s.SegmentAt(2.0f, 0.0f), 1);
  EXPECT_EQ(s.SegmentAt(2.0f, 2.0f), 5);
  EXPECT_EQ(s.SegmentAt(5.0f, 3.0f), 6);
  EXPECT_EQ(s.SegmentAt(7.0f, 5.0f), 11);   // last full-resolution pixel
  EXPECT_EQ(s.SegmentAt(-0.5f, -0.5f), 0);  // the corner of the first pixel
  // Rounding of the working size: up to half a working pixel past the end clamps.
  EXPECT_EQ(s.SegmentAt(8.2f, 6.2f), 11);
  // Outside.
  EXPECT_EQ(s.SegmentAt(-0.6f, 0.0f), -1);
  EXPECT_EQ(s.SegmentAt(0.0f, -1.0f), -1);
  EXPECT_EQ(s.SegmentAt(8.6f, 0.0f), -1);
  EXPECT_EQ(s.SegmentAt(0.0f, 6.6f), -1);
  EXPECT_EQ(s.SegmentAt(1e9f, 0.0f), -1);
  EXPECT_EQ(s.SegmentAt(std::nanf(""), 0.0f), -1);

  // Scale 1: a point maps to the pixel whose square contains it.
  const SceneSegmentation same = Grid4x3(1.0);
  EXPECT_EQ(same.SegmentAt(3.0f, 2.0f), 11);
  EXPECT_EQ(same.SegmentAt(2.49f, 1.51f), 10);
  EXPECT_EQ(same.SegmentAt(2.51f, 1.49f), 7);
  EXPECT_EQ(same.SegmentAt(4.6f, 0.0f), -1);

  EXPECT_EQ(SceneSegmentation().SegmentAt(0.0f, 0.0f), -1);
}

TEST(CompactLabelsTest, RenumbersInFirstAppearanceOrder) {
  cv::Mat labels = (cv::Mat_<int>(2, 4) << 7, 7, 3, 42,  //
                    -5, 3, 7, 42);
  EXPECT_EQ(CompactLabels(&labels), 4);
  const cv::Mat expected = (cv::Mat_<int>(2, 4) << 0, 0, 1, 2,  //
                            3, 1, 0, 2);
  EXPECT_EQ(cv::countNonZero(labels != expected), 0) << labels;

  // Sparse ids far apart take the other path and give the same answer.
  cv::Mat sparse = (cv::Mat_<int>(1, 5) << 2000000000, -2000000000, 5, 2000000000, 5);
  EXPECT_EQ(CompactLabels(&sparse), 3);
  const cv::Mat sparse_expected = (cv::Mat_<int>(1, 5) << 0, 1, 2, 0, 2);
  EXPECT_EQ(cv::countNonZero(sparse != sparse_expected), 0) << sparse;

  // Already compact stays; empty gives 0.
  cv::Mat compact = (cv::Mat_<int>(1, 3) << 0, 1, 2);
  EXPECT_EQ(CompactLabels(&compact), 3);
  EXPECT_EQ(compact.at<int>(0, 2), 2);
  cv::Mat empty(0, 0, CV_32S);
  EXPECT_EQ(CompactLabels(&empty), 0);
}

}  // namespace
}  // namespace placerec
