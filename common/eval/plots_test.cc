#include "common/eval/plots.h"

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace placerec
