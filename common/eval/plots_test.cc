#include "common/eval/plots.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <string>

namespace placerec {
namespace {

RunScore ExampleScore(double scale) {
  RunScore score;
  score.revisit_frames = 10;
  int tp = 0;
  int fp = 0;
  for (int i = 0; i < 12; ++i) {
    (i % 3 == 2 || i * scale > 8 ? fp : tp)++;
    PrPoint p;
    p.threshold = 1.0 - i / 12.0;
    p.true_positives = tp;
    p.false_positives = fp;
    p.precision = static_cast<double>(tp) / (tp + fp);
    p.recall = tp / 10.0;
    score.curve.push_back(p);
  }
  score.max_f1 = 0.6;
  score.precision_at_max_f1 = score.curve[6].precision;
  score.recall_at_max_f1 = score.curve[6].recall;
  return score;
}

TEST(PlotsTest, WritesAPngOfTheRequestedSize) {
  const std::string path = ::testing::TempDir() + "/placerec_plots_test.png";
  std::remove(path.c_str());
  const std::vector<PrCurve> curves = {
      {"system a", ExampleScore(1.0)}, {"system b", ExampleScore(2.0)}, {"no claims", RunScore()}};
  ASSERT_TRUE(WritePrCurvePng(path, "corridor_loop", curves, 640, 480).ok());
  const cv::Mat image = cv::imread(path, cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.cols, 640);
  EXPECT_EQ(image.rows, 480);
  EXPECT_EQ(image.type(), CV_8UC3);
  // Not blank: the corner is white, the picture as a whole is not.
  EXPECT_EQ(image.at<cv::Vec3b>(0, 0), cv::Vec3b(255, 255, 255));
  EXPECT_LT(cv::mean(image)[0], 254.0);
  std::remove(path.c_str());
}

TEST(PlotsTest, FailsOnAnUnwritablePathOrABadSize) {
  const std::vector<PrCurve> curves = {{"a", ExampleScore(1.0)}};
  EXPECT_EQ(WritePrCurvePng(::testing::TempDir() + "/no_such_dir/pr.png", "t", curves).code(),
            StatusCode::kIoError);
  EXPECT_EQ(WritePrCurvePng(::testing::TempDir() + "/pr.png", "t", curves, 10, 10).code(),
            StatusCode::kInvalidArgument);
}

// Pixels of exactly `colour` (BGR): bars are filled without anti-aliasing.
int PixelsOf(const cv::Mat& image, const cv::Vec3b& colour) {
  int n = 0;
  for (int y = 0; y < image.rows; ++y) {
    for (int x = 0; x < image.cols; ++x) n += image.at<cv::Vec3b>(y, x) == colour;
  }
  return n;
}

TEST(PlotsTest, BarsAreAsTallAsTheirValues) {
  const std::string path = ::testing::TempDir() + "/placerec_bars_test.png";
  std::remove(path.c_str());
  // The first two palette colours (tab10 blue and orange, BGR).
  const cv::Vec3b first(180, 119, 31);
  const cv::Vec3b second(14, 127, 255);
  ASSERT_TRUE(WriteBarChartPng(path, "object IoU", "mean IoU (%)", {"all (10)", "tree (4)"},
                               {{"default", {20.0, 60.0}}, {"baseline", {80.0, NAN}}}, 800, 500)
                  .ok());
  const cv::Mat image = cv::imread(path, cv::IMREAD_COLOR);
  ASSERT_EQ(image.size(), cv::Size(800, 500));
  // Equal widths, so areas go as heights: default's 20 + 60 against baseline's 80 (its second
  // value is missing), plus one legend swatch each.
  const int a = PixelsOf(image, first);
  const int b = PixelsOf(image, second);
  ASSERT_GT(b, 1000);
  EXPECT_NEAR(static_cast<double>(a) / b, 1.0, 0.05);
  ASSERT_TRUE(WriteBarChartPng(path, "", "", {"one"}, {{"a", {20.0}}, {"b", {80.0}}}).ok());
  const cv::Mat two = cv::imread(path, cv::IMREAD_COLOR);
  EXPECT_NEAR(static_cast<double>(PixelsOf(two, second)) / PixelsOf(two, first), 4.0, 0.3);
  std::remove(path.c_str());
}

TEST(PlotsTest, BarChartRefusesWhatItCannotDraw) {
  const std::string path = ::testing::TempDir() + "/placerec_bars_bad.png";
  EXPECT_EQ(WriteBarChartPng(path, "t", "y", {"a", "b"}, {{"s", {1.0}}}).code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(WriteBarChartPng(path, "t", "y", {"a"}, {{"s", {101.0}}}).code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(WriteBarChartPng(path, "t", "y", {}, {}).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(WriteBarChartPng(path, "t", "y", {"a"}, {{"s", {1.0}}}, 100, 100).code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(
      WriteBarChartPng(::testing::TempDir() + "/no_such_dir/b.png", "t", "y", {"a"}, {{"s", {1.0}}})
          .code(),
      StatusCode::kIoError);
}

TEST(PlotsTest, ConfusionMatrixPngHasARowAndColumnPerClass) {
  const std::string path = ::testing::TempDir() + "/placerec_confusion_test.png";
  ASSERT_TRUE(WriteConfusionMatrixPng(path, "confusion", {"car", "building", "body"},
                                      {{8, 2, 0, 0}, {0, 10, 0, 1}, {1, 1, 3, 0}})
                  .ok());
  const cv::Mat picture = cv::imread(path);
  ASSERT_FALSE(picture.empty());
  // Three cells of 34 pixels each way plus labels.
  EXPECT_GT(picture.cols, 3 * 34);
  EXPECT_GT(picture.rows, 3 * 34);
  EXPECT_EQ(WriteConfusionMatrixPng(path, "t", {"a", "b"}, {{1, 2}}).code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(WriteConfusionMatrixPng(path, "t", {"a", "b"}, {{1}, {2}}).code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(WriteConfusionMatrixPng("", "t", {"a"}, {{1}}).code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace placerec
