#include "common/eval/paste.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

namespace placerec {
namespace {

CutObject Disc() {
  CutObject disc;
  disc.bgr = cv::Mat(40, 40, CV_8UC3, cv::Scalar(0, 0, 250));
  disc.mask = cv::Mat::zeros(40, 40, CV_8U);
  cv::circle(disc.mask, cv::Point(20, 20), 19, cv::Scalar(255), -1);
  return disc;
}

TEST(PasteTest, PastedObjectCoversTheAskedShareWhereTheBoxSays) {
  cv::Mat frame(200, 300, CV_8UC3, cv::Scalar(100, 100, 100));
  double covered = 0;
  const cv::Rect box = PasteObject(Disc(), 0.05, 0.5, 0.25, 0.5, &frame, &covered);
  ASSERT_FALSE(box.empty());
  // The disc's area is 5 % of the frame: about pi r^2 = 3000 pixels; its box covers 4 / pi of it.
  EXPECT_NEAR(box.area() * 3.14159 / 4 / (200.0 * 300.0), 0.05, 0.01);
  EXPECT_NEAR(covered, 0.05, 0.005);
  EXPECT_GT(static_cast<double>(box.area()) / (200.0 * 300.0), 0.06);
  EXPECT_NEAR(box.x + box.width / 2.0, 150, 3);
  cv::Mat changed;
  cv::absdiff(frame, cv::Scalar(100, 100, 100), changed);
  cv::cvtColor(changed, changed, cv::COLOR_BGR2GRAY);
  const cv::Rect touched = cv::boundingRect(changed > 10);
  EXPECT_GT(BoxIoU(touched, box), 0.8);
  // Colour moved towards the grey surroundings, not kept pure red.
  const cv::Vec3b centre = frame.at<cv::Vec3b>(box.y + box.height / 2, box.x + box.width / 2);
  EXPECT_GT(centre[0], 20);
  EXPECT_GT(centre[2], centre[0]);
}

TEST(PasteTest, ColourShiftZeroKeepsTheObjectsOwnColours) {
  cv::Mat frame(200, 300, CV_8UC3, cv::Scalar(100, 100, 100));
  const cv::Rect box = PasteObject(Disc(), 0.05, 0.5, 0.25, 0.0, &frame);
  ASSERT_FALSE(box.empty());
  const cv::Vec3b centre = frame.at<cv::Vec3b>(box.y + box.height / 2, box.x + box.width / 2);
  EXPECT_NEAR(centre[0], 0, 3);
  EXPECT_NEAR(centre[1], 0, 3);
  EXPECT_NEAR(centre[2], 250, 3);
  // All the way: the region's grey.
  cv::Mat grey(200, 300, CV_8UC3, cv::Scalar(100, 100, 100));
  const cv::Rect all = PasteObject(Disc(), 0.05, 0.5, 0.25, 1.0, &grey);
  ASSERT_FALSE(all.empty());
  const cv::Vec3b middle = grey.at<cv::Vec3b>(all.y + all.height / 2, all.x + all.width / 2);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(middle[c], 100, 4) << c;
}

TEST(PasteTest, TooLargeObjectIsNotPasted) {
  cv::Mat frame(20, 20, CV_8UC3, cv::Scalar(0, 0, 0));
  EXPECT_TRUE(PasteObject(Disc(), 2.0, 0, 0, 0.5, &frame).empty());
}

TEST(PasteTest, PaintOverFillsFromTheSurroundings) {
  cv::Mat frame(100, 100, CV_8UC3, cv::Scalar(50, 60, 70));
  frame(cv::Rect(40, 40, 20, 20)).setTo(cv::Scalar(255, 255, 255));
  const cv::Rect painted = PaintOver(cv::Rect(38, 38, 24, 24), &frame);
  EXPECT_EQ(painted, cv::Rect(38, 38, 24, 24));
  const cv::Vec3b centre = frame.at<cv::Vec3b>(50, 50);
  EXPECT_NEAR(centre[0], 50, 3);
  EXPECT_NEAR(centre[2], 70, 3);
}

TEST(PasteTest, BoxIoU) {
  EXPECT_DOUBLE_EQ(BoxIoU(cv::Rect(0, 0, 10, 10), cv::Rect(0, 0, 10, 10)), 1.0);
  EXPECT_DOUBLE_EQ(BoxIoU(cv::Rect(0, 0, 10, 10), cv::Rect(5, 0, 10, 10)), 50.0 / 150.0);
  EXPECT_DOUBLE_EQ(BoxIoU(cv::Rect(), cv::Rect(0, 0, 10, 10)), 0.0);
}

TEST(PasteTest, MissingDatasetIsNotFound) {
  EXPECT_EQ(CutTestObjects("/nonexistent", CutOptions()).status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace placerec
