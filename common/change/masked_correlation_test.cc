#include "common/change/masked_correlation.h"

#include <cmath>

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

namespace placerec {
namespace {

// The masked normalised correlation of `templ` with `image` at (x, y), computed directly.
double Correlation(const cv::Mat& image, const cv::Mat& templ, const cv::Mat& mask, int x, int y) {
  double n = 0, sum_i = 0, sum_t = 0;
  for (int r = 0; r < templ.rows; ++r) {
    for (int c = 0; c < templ.cols; ++c) {
      if (mask.at<uchar>(r, c) == 0) continue;
      n += 1;
      sum_i += image.at<uchar>(y + r, x + c);
      sum_t += templ.at<uchar>(r, c);
    }
  }
  double cross = 0, var_i = 0, var_t = 0;
  for (int r = 0; r < templ.rows; ++r) {
    for (int c = 0; c < templ.cols; ++c) {
      if (mask.at<uchar>(r, c) == 0) continue;
      const double i = image.at<uchar>(y + r, x + c) - sum_i / n;
      const double t = templ.at<uchar>(r, c) - sum_t / n;
      cross += i * t;
      var_i += i * i;
      var_t += t * t;
    }
  }
  return cross / std::sqrt(var_i * var_t);
}

// The soak's one "internal error" (in recognize > change): OpenCV 4.6's masked matchTemplate
// throws when the scores are one column by four rows, a shape the "seen elsewhere" window takes
// when the stored view cuts it to the template's width and three rows more.
TEST(MaskedCorrelationTest, EveryWindowShapeGivesTheCorrelation) {
  cv::RNG rng(7);
  for (int extra_rows = 0; extra_rows <= 5; ++extra_rows) {
    for (int extra_cols = 0; extra_cols <= 5; ++extra_cols) {
      cv::Mat templ(8, 9, CV_8U), image(8 + extra_rows, 9 + extra_cols, CV_8U);
      rng.fill(templ, cv::RNG::UNIFORM, 0, 256);
      rng.fill(image, cv::RNG::UNIFORM, 0, 256);
      cv::Mat mask(templ.size(), CV_8U, cv::Scalar(255));
      mask(cv::Rect(0, 0, 3, 2)).setTo(0);
      cv::Mat scores;
      ASSERT_NO_THROW(MaskedCorrelation(image, templ, mask, &scores))
          << extra_cols + 1 << " x " << extra_rows + 1;
      ASSERT_EQ(scores.size(), cv::Size(extra_cols + 1, extra_rows + 1));
      ASSERT_EQ(scores.type(), CV_32F);
      for (int y = 0; y < scores.rows; ++y) {
        for (int x = 0; x < scores.cols; ++x) {
          EXPECT_NEAR(scores.at<float>(y, x), Correlation(image, templ, mask, x, y), 1e-3)
              << "window " << scores.cols << " x " << scores.rows << " at " << x << ", " << y;
        }
      }
    }
  }
}

// When OpenCV's own call stops throwing for this shape (a later OpenCV), the transposition in
// MaskedCorrelation can go: this test then fails and says so.
TEST(MaskedCorrelationTest, OpenCvThrowsForScoresOfOneColumnByFourRows) {
  cv::Mat templ(8, 9, CV_8U, cv::Scalar(0)), image(11, 9, CV_8U, cv::Scalar(0));
  cv::randu(templ, 0, 256);
  cv::randu(image, 0, 256);
  const cv::Mat mask(templ.size(), CV_8U, cv::Scalar(255));
  cv::Mat scores;
  EXPECT_THROW(cv::matchTemplate(image, templ, scores, cv::TM_CCOEFF_NORMED, mask), cv::Exception);
}

}  // namespace
}  // namespace placerec
