// Tests of the object description (seed §4.1): the Poisson solution against shapes whose
// solution is known (a disc, a square, a rectangle), the shape measures on shapes whose
// orientation and concavity are obvious, the parts-layout blocks on hand-counted texton maps,
// sizes with the shipped dictionary, invariances and the errors for bad input.

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "common/classification/object_description.h"
#include "common/image/image.h"
#include "common/organization/filter_bank.h"
#include "common/organization/textons.h"

namespace placerec {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Pixels whose centre is closer than `r` to (cx, cy) in a `size` x `size` mask.
cv::Mat Disc(int size, double cx, double cy, double r) {
  cv::Mat mask = cv::Mat::zeros(size, size, CV_8U);
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      if ((x - cx) * (x - cx) + (y - cy) * (y - cy) < r * r) mask.at<uint8_t>(y, x) = 255;
    }
  }
  return mask;
}

// An L: a vertical arm x in [10, 30), y in [10, 70) and a horizontal arm x in [10, 70),
// y in [50, 70). Its reflex (concave) corner is the pixel (29, 49).
cv::Mat LShape() {
  cv::Mat mask = cv::Mat::zeros(80, 80, CV_8U);
  mask(cv::Rect(10, 10, 20, 60)) = 255;
  mask(cv::Rect(10, 50, 60, 20)) = 255;
  return mask;
}

// Value at (x, y) of the solution of Delta U = -1 on [0, a] x [0, b], U = 0 on the sides:
// the double sine series sum over odd m, n of
// 16 / (pi^2 m n (m^2 pi^2 / a^2 + n^2 pi^2 / b^2)) sin(m pi x / a) sin(n pi y / b).
double RectangleSeries(double a, double b, double x, double y) {
  double sum = 0;
  for (int m = 1; m < 2000; m += 2) {
    for (int n = 1; n < 2000; n += 2) {
      const double lambda = kPi * kPi * (m * m / (a * a) + n * n / (b * b));
      sum += 16.0 / (kPi * kPi * m * n * lambda) * std::sin(m * kPi * x / a) *
             std::sin(n * kPi * y / b);
    }
  }
  return sum;
}

double Max(const cv::Mat& image) {
  double max_value = 0;
  cv::minMaxLoc(image, nullptr, &max_value);
  return max_value;
}

// A k-texton dictionary with random centres in raw units (mean 0, scale 1).
TextonModel SmallTextons(int k) {
  TextonModel model;
  model.mean = cv::Mat::zeros(1, kTextonFeatureSize, CV_32F);
  model.inv_std = cv::Mat::ones(1, kTextonFeatureSize, CV_32F);
  model.centres.create(k, kTextonFeatureSize, CV_32F);
  cv::RNG rng(5);
  rng.fill(model.centres, cv::RNG::UNIFORM, -50.0, 50.0);
  return model;
}

// A 320x240 textured test image (fixed seed): smooth colour ramps plus noise and stripes.
cv::Mat TestImage() {
  cv::Mat bgr(240, 320, CV_8UC3);
  cv::RNG rng(11);
  for (int y = 0; y < bgr.rows; ++y) {
    for (int x = 0; x < bgr.cols; ++x) {
      const int stripe = ((x / 7) % 2) * 60;
      bgr.at<cv::Vec3b>(y, x) = cv::Vec3b(cv::saturate_cast<uint8_t>(x * 0.7 + rng.uniform(0, 40)),
                                          cv::saturate_cast<uint8_t>(y + stripe),
                                          cv::saturate_cast<uint8_t>(200 - y * 0.5 + stripe));
    }
  }
  return bgr;
}

TextonModel ShippedTextons() {
  StatusOr<TextonModel> model = LoadTextons(std::string(PLACEREC_MODELS_DIR) + "/textons.yml");
  CHECK(model.ok()) << model.status().ToString();
  return *model;
}

// ---- Options ----

TEST(ObjectDescriptionOptionsTest, DefaultsAreTheSeedsAndBadValuesAreRejected) {
  const ObjectDescriptionOptions defaults;
  std::string error;
  EXPECT_TRUE(defaults.Check(&error)) << error;
  EXPECT_EQ(defaults.orientation_gamma, 3.0);  // seed §4.1.3, eq. 4.3-4.4
  EXPECT_EQ(defaults.concavity_delta, 4.0);    // seed §4.1.3, eq. 4.6

  ObjectDescriptionOptions bad;
  bad.shape_max_side = 4;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_NE(error.find("shape_max_side"), std::string::npos) << error;
  bad = ObjectDescriptionOptions();
  bad.orientation_gamma = 0;
  EXPECT_FALSE(bad.Check(&error));
  bad.orientation_gamma = std::nan("");
  EXPECT_FALSE(bad.Check(&error));
  bad = ObjectDescriptionOptions();
  bad.concavity_delta = -1;
  EXPECT_FALSE(bad.Check(&error));
  bad.concavity_delta = INFINITY;
  EXPECT_FALSE(bad.Check(&error));
}

// ---- Poisson equation (seed eq. 4.1-4.2) ----

TEST(PoissonTest, EveryMaskPixelSatisfiesTheDiscreteEquationWithZeroOutside) {
  // An irregular blob touching the image's border: the image's outside is boundary too.
  cv::Mat mask = cv::Mat::zeros(40, 50, CV_8U);
  cv::ellipse(mask, cv::Point(20, 12), cv::Size(25, 12), 30, 0, 360, cv::Scalar(255), -1);
  cv::circle(mask, cv::Point(40, 30), 8, cv::Scalar(255), -1);
  ASSERT_GT(cv::countNonZero(mask.row(0)), 0);
  const StatusOr<cv::Mat> u = SolvePoisson(mask);
  ASSERT_TRUE(u.ok()) << u.status().ToString();
  ASSERT_EQ(u->type(), CV_64F);
  ASSERT_EQ(u->size(), mask.size());
  auto at = [&](int x, int y) {
    if (x < 0 || y < 0 || x >= mask.cols || y >= mask.rows) return 0.0;
    return u->at<double>(y, x);
  };
  for (int y = 0; y < mask.rows; ++y) {
    for (int x = 0; x < mask.cols; ++x) {
      if (mask.at<uint8_t>(y, x) == 0) {
        EXPECT_EQ(at(x, y), 0.0) << "outside the mask at " << x << ", " << y;
        continue;
      }
      EXPECT_GT(at(x, y), 0.0);
      const double laplacian =
          at(x + 1, y) + at(x - 1, y) + at(x, y + 1) + at(x, y - 1) - 4 * at(x, y);
      EXPECT_NEAR(laplacian, -1.0, 1e-9) << "at " << x << ", " << y;
    }
  }
}

TEST(PoissonTest, DiscMatchesTheAnalyticSolutionAndConvergesWithRadius) {
  // U = (R^2 - r^2) / 4 for Delta U = -1. The staircase boundary of a pixel disc costs a few
  // per cent of the maximum, shrinking as R grows (measured: 5.0 % at R = 20, 2.7 % at 40).
  double previous_error = 0;
  for (const double radius : {20.0, 40.0}) {
    const int size = static_cast<int>(2 * radius) + 11;
    const double c = (size - 1) / 2.0;
    const cv::Mat mask = Disc(size, c, c, radius);
    const StatusOr<cv::Mat> u = SolvePoisson(mask);
    ASSERT_TRUE(u.ok()) << u.status().ToString();
    const double peak = radius * radius / 4;
    double max_error = 0;
    for (int y = 0; y < size; ++y) {
      for (int x = 0; x < size; ++x) {
        if (mask.at<uint8_t>(y, x) == 0) continue;
        const double r2 = (x - c) * (x - c) + (y - c) * (y - c);
        max_error = std::max(max_error, std::abs(u->at<double>(y, x) - (peak - r2 / 4)));
      }
    }
    EXPECT_NEAR(Max(*u), peak, 0.03 * peak) << "R = " << radius;
    if (radius == 20.0) {
      EXPECT_LT(max_error, 0.06 * peak);
    } else {
      EXPECT_LT(max_error, 0.035 * peak);
      EXPECT_LT(max_error / peak, 0.7 * previous_error) << "the error should shrink with R";
    }
    previous_error = max_error / peak;
  }
}

TEST(PoissonTest, SquareMaximumIsTheKnownSeriesValue) {
  // n x n pixels inside a zero frame: the 5-point scheme on a square of side a = n + 1.
  // Max U = 0.0737 a^2 (the series gives 0.07367).
  const int n = 63;
  const double a = n + 1;
  cv::Mat mask = cv::Mat::zeros(n + 2, n + 2, CV_8U);
  mask(cv::Rect(1, 1, n, n)) = 255;
  const StatusOr<cv::Mat> u = SolvePoisson(mask);
  ASSERT_TRUE(u.ok()) << u.status().ToString();
  EXPECT_NEAR(Max(*u) / (a * a), 0.0737, 0.0001);
  const double series = RectangleSeries(a, a, a / 2, a / 2);
  EXPECT_NEAR(Max(*u), series, 0.001 * series);
  // Maximum at the centre pixel.
  EXPECT_EQ(u->at<double>(32, 32), Max(*u));
}

TEST(PoissonTest, RectangleFillingTheImageMatchesTheSeriesInsideAndAtTheCentre) {
  // The mask is the whole 95 x 47 image: the boundary is the image's outside, a 96 x 48
  // rectangle.
  const int w = 95;
  const int h = 47;
  const cv::Mat mask(h, w, CV_8U, cv::Scalar(255));
  const StatusOr<cv::Mat> u = SolvePoisson(mask);
  ASSERT_TRUE(u.ok()) << u.status().ToString();
  const double centre = RectangleSeries(w + 1, h + 1, (w + 1) / 2.0, (h + 1) / 2.0);
  EXPECT_NEAR(u->at<double>(23, 47), centre, 0.002 * centre);
  // Off centre too: pixel (x, y) is at (x + 1, y + 1) in the rectangle.
  for (const cv::Point p : {cv::Point(10, 5), cv::Point(70, 30), cv::Point(47, 2)}) {
    const double expected = RectangleSeries(w + 1, h + 1, p.x + 1, p.y + 1);
    EXPECT_NEAR(u->at<double>(p), expected, 0.01 * centre) << p;
  }
}

// ---- Shape measures (seed eq. 4.3-4.6) ----

TEST(ShapeMapsTest, PhiIsNearlyConstantOnADisc) {
  // Phi = U + |grad U|^2 = R^2 / 4 everywhere on a disc (Delta U = -1). With the seed's
  // Delta U = -4 it would run from R^2 to 4 R^2 (a relative spread of about 0.35).
  const double radius = 40;
  const cv::Mat mask = Disc(91, 45, 45, radius);
  const StatusOr<ShapeMaps> maps = ComputeShapeMaps(mask, ObjectDescriptionOptions());
  ASSERT_TRUE(maps.ok()) << maps.status().ToString();
  cv::Scalar mean;
  cv::Scalar stddev;
  cv::meanStdDev(maps->phi, mean, stddev, mask);
  EXPECT_NEAR(mean[0], radius * radius / 4, 0.03 * radius * radius / 4);
  EXPECT_LT(stddev[0] / mean[0], 0.06);
  // So the concave measure is flat: close to 1 / (1 + e^-4) = 0.982 everywhere.
  cv::meanStdDev(maps->w_concave, mean, stddev, mask);
  EXPECT_GT(mean[0], 0.95);
  EXPECT_LT(stddev[0], 0.02);
}

TEST(ShapeMapsTest, ConcaveMeasurePeaksAtTheReflexCornerOfAnL) {
  const cv::Mat mask = LShape();
  const StatusOr<ShapeMaps> maps = ComputeShapeMaps(mask, ObjectDescriptionOptions());
  ASSERT_TRUE(maps.ok()) << maps.status().ToString();
  cv::Point peak;
  cv::minMaxLoc(maps->phi, nullptr, nullptr, nullptr, &peak);
  EXPECT_LE(std::abs(peak.x - 29) + std::abs(peak.y - 49), 2) << peak;
  // Phi_n = 1 there: W_c = 1 / (1 + e^-4).
  EXPECT_NEAR(maps->w_concave.at<double>(peak), 1 / (1 + std::exp(-4.0)), 1e-9);
  // Convex corners and the arms' middles are much less concave.
  EXPECT_LT(maps->w_concave.at<double>(10, 10), 0.7);
  EXPECT_LT(maps->w_concave.at<double>(69, 69), 0.7);
  EXPECT_LT(maps->w_concave.at<double>(30, 20), 0.8);
  // Phi is normalised by its largest absolute value: W_c in (0.5, 1 / (1 + e^-4)].
  double min_wc = 1;
  cv::minMaxLoc(maps->w_concave, &min_wc, nullptr, nullptr, nullptr, mask);
  EXPECT_GT(min_wc, 0.5);
}

TEST(ShapeMapsTest, BarsAreVerticalOrHorizontalWhereTheSeedSaysSo) {
  // In the L's vertical arm the leading eigenvector of the Hessian is across the arm, along x:
  // alpha = 0, W_0 (the seed's vertical measure) is near 1; in the horizontal arm the reverse.
  const cv::Mat mask = LShape();
  const StatusOr<ShapeMaps> maps = ComputeShapeMaps(mask, ObjectDescriptionOptions());
  ASSERT_TRUE(maps.ok()) << maps.status().ToString();
  const cv::Point vertical_arm(20, 25);
  const cv::Point horizontal_arm(55, 60);
  EXPECT_LT(maps->angle.at<double>(vertical_arm), 0.05);
  EXPECT_GT(maps->w_vertical.at<double>(vertical_arm), 0.85);
  EXPECT_LT(maps->w_horizontal.at<double>(vertical_arm), 0.02);
  EXPECT_GT(maps->angle.at<double>(horizontal_arm), kPi / 2 - 0.05);
  EXPECT_GT(maps->w_horizontal.at<double>(horizontal_arm), 0.85);
  EXPECT_LT(maps->w_vertical.at<double>(horizontal_arm), 0.02);
  // Eq. 4.3-4.4 with gamma = 3.
  for (const cv::Point p : {vertical_arm, horizontal_arm, cv::Point(15, 55)}) {
    const double alpha = maps->angle.at<double>(p);
    EXPECT_NEAR(maps->w_vertical.at<double>(p), std::exp(-3 * alpha), 1e-12);
    EXPECT_NEAR(maps->w_horizontal.at<double>(p), std::exp(-3 * std::abs(kPi / 2 - alpha)), 1e-12);
  }
}

// ---- Shape numbers (seed eq. 4.7) ----

TEST(ShapeFeaturesTest, DiscMomentsAreThoseOfAUniformDiscInUnitsOfSqrtArea) {
  const StatusOr<std::vector<float>> f = ShapeFeatures(Disc(101, 50, 50, 45), {});
  ASSERT_TRUE(f.ok()) << f.status().ToString();
  ASSERT_EQ(f->size(), 30u);
  // Concave measure nearly flat on a disc: m00 is the mean weight, odd moments vanish by
  // symmetry, m20 = m02 = E[x^2] / area = (R^2 / 4) / (pi R^2) = 1 / (4 pi).
  const float* concave = f->data() + 20;
  EXPECT_GT(concave[0], 0.95f);
  for (int i : {1, 2, 4, 6, 7, 8, 9}) EXPECT_NEAR(concave[i], 0.0, 1e-6) << "moment " << i;
  EXPECT_NEAR(concave[3], 1 / (4 * kPi), 0.002);
  EXPECT_NEAR(concave[5], 1 / (4 * kPi), 0.002);
  // A disc has no preferred direction: as much vertical as horizontal.
  EXPECT_NEAR((*f)[0], (*f)[10], 0.01);
}

TEST(ShapeFeaturesTest, TransposingSwapsTheVerticalAndHorizontalMeasures) {
  // A shape without a diagonal symmetry (an L with arms 20 and 12 thick and a disc on the
  // thinner arm). Transposed, W_0 and W_pi/2 trade places and every m_pq becomes m_qp.
  cv::Mat mask = cv::Mat::zeros(80, 80, CV_8U);
  mask(cv::Rect(10, 10, 20, 60)) = 255;
  mask(cv::Rect(10, 58, 60, 12)) = 255;
  cv::circle(mask, cv::Point(50, 52), 9, cv::Scalar(255), -1);
  const cv::Mat transposed = mask.t();
  const StatusOr<std::vector<float>> a = ShapeFeatures(mask, {});
  const StatusOr<std::vector<float>> b = ShapeFeatures(transposed, {});
  ASSERT_TRUE(a.ok() && b.ok());
  // Index of m_qp for the moment at index i (order m00 m10 m01 m20 m11 m02 m30 m21 m12 m03).
  const int swapped[10] = {0, 2, 1, 5, 4, 3, 9, 8, 7, 6};
  for (int i = 0; i < 10; ++i) {
    EXPECT_NEAR((*a)[i], (*b)[10 + swapped[i]], 1e-5) << "W_0 moment " << i;
    EXPECT_NEAR((*a)[10 + i], (*b)[swapped[i]], 1e-5) << "W_pi/2 moment " << i;
    EXPECT_NEAR((*a)[20 + i], (*b)[20 + swapped[i]], 1e-5) << "W_c moment " << i;
  }
  // And the shape is not symmetric, so the swap is not trivially satisfied.
  EXPECT_GT(std::abs((*a)[0] - (*a)[10]), 0.01);
}

TEST(ShapeFeaturesTest, MovedAndScaledShapesGiveTheSameNumbers) {
  const StatusOr<std::vector<float>> base = ShapeFeatures(Disc(120, 50, 50, 25), {});
  ASSERT_TRUE(base.ok());
  // Moved: identical.
  const StatusOr<std::vector<float>> moved = ShapeFeatures(Disc(120, 80, 63, 25), {});
  ASSERT_TRUE(moved.ok());
  for (int i = 0; i < 30; ++i) EXPECT_NEAR((*base)[i], (*moved)[i], 1e-6) << i;
  // Twice the radius, and eight times (the solve then runs on the 128-pixel working grid): the
  // concave measure's moments are equal up to the discretisation of the boundary. A disc's
  // Hessian is isotropic (U = (R^2 - r^2) / 4), so its orientation, and with it how W_0 and
  // W_pi/2 spread, follows the pixel staircase (m20 of W_0 measured 0.098, 0.085, 0.061 at
  // R = 25, 50, 200); only their equality is a property of the disc.
  for (const double radius : {50.0, 200.0}) {
    const int size = static_cast<int>(2 * radius) + 10;
    const StatusOr<std::vector<float>> scaled =
        ShapeFeatures(Disc(size, size / 2.0, size / 2.0, radius), {});
    ASSERT_TRUE(scaled.ok());
    for (int i = 20; i < 30; ++i) EXPECT_NEAR((*base)[i], (*scaled)[i], 0.01) << "R " << radius;
    EXPECT_FLOAT_EQ((*scaled)[0], (*scaled)[10]) << "R " << radius;
  }
  // A bar has a defined orientation: all 30 numbers hold under scaling (measured: within
  // 0.015), while its aspect shows.
  cv::Mat small = cv::Mat::zeros(60, 60, CV_8U);
  small(cv::Rect(10, 20, 40, 20)) = 255;
  const StatusOr<std::vector<float>> f_small = ShapeFeatures(small, {});
  ASSERT_TRUE(f_small.ok());
  for (const double factor : {2.0, 5.0}) {
    cv::Mat large;
    cv::resize(small, large, cv::Size(), factor, factor, cv::INTER_NEAREST);
    const StatusOr<std::vector<float>> f_large = ShapeFeatures(large, {});
    ASSERT_TRUE(f_large.ok());
    for (int i = 0; i < 30; ++i) EXPECT_NEAR((*f_small)[i], (*f_large)[i], 0.02) << factor;
  }
  EXPECT_GT((*f_small)[10], (*f_small)[0] + 0.1) << "a wide bar is mostly horizontal";
  EXPECT_GT((*f_small)[23], 2 * (*f_small)[25]) << "and spreads more in x than in y";
}

TEST(ShapeFeaturesTest, AThinLineSurvivesTheWorkingResolution) {
  cv::Mat mask = cv::Mat::zeros(20, 600, CV_8U);
  mask.row(10) = 255;  // 600 x 1: 128 x 0.2 at the working resolution
  const StatusOr<std::vector<float>> f = ShapeFeatures(mask, {});
  ASSERT_TRUE(f.ok()) << f.status().ToString();
  for (float v : *f) EXPECT_TRUE(std::isfinite(v));
  EXPECT_GT((*f)[10], 0.9f) << "a horizontal line is horizontal";
}

// ---- Appearance (seed §4.1.1) and parts layout (§4.1.2) ----

TEST(AppearanceTest, HistogramOfTheMaskPixelsThenCentroidHeight) {
  const int k = 4;
  cv::Mat ids(100, 50, CV_16U, cv::Scalar(3));  // texton 3 outside the object
  cv::Mat mask = cv::Mat::zeros(100, 50, CV_8U);
  mask(cv::Rect(0, 20, 10, 40)) = 255;  // rows 20..59: centroid row 39.5
  ids(cv::Rect(0, 20, 10, 30)) = 0;     // 300 pixels of texton 0
  ids(cv::Rect(0, 50, 10, 10)) = 2;     // 100 of texton 2
  const StatusOr<std::vector<float>> f = AppearanceFeatures(ids, mask, k);
  ASSERT_TRUE(f.ok()) << f.status().ToString();
  ASSERT_EQ(f->size(), 5u);
  EXPECT_FLOAT_EQ((*f)[0], 0.75f);
  EXPECT_FLOAT_EQ((*f)[1], 0.0f);
  EXPECT_FLOAT_EQ((*f)[2], 0.25f);
  EXPECT_FLOAT_EQ((*f)[3], 0.0f);
  EXPECT_FLOAT_EQ((*f)[4], 0.4f);  // (39.5 + 0.5) / 100
}

// The mask of the parts-layout tests: a tall left part (x 10..29, y 20..59, 800 pixels) and a
// short right part (x 30..49, y 20..29, 200 pixels). Box x [10, 50), y [20, 60); centroid
// (24, 37) in continuous coordinates, not the box's centre (30, 40). Fine lines: x 17 and 37,
// y 28.5 and 48.5.
cv::Mat PartsMask() {
  cv::Mat mask = cv::Mat::zeros(70, 60, CV_8U);
  mask(cv::Rect(10, 20, 20, 40)) = 255;
  mask(cv::Rect(30, 20, 20, 10)) = 255;
  return mask;
}

TEST(PartsLayoutTest, ColumnsAreCutAtTheCentroidThenHalfWayToTheSides) {
  const int k = 40;
  const cv::Mat mask = PartsMask();
  cv::Mat ids = cv::Mat::zeros(mask.size(), CV_16U);
  for (int x = 10; x < 50; ++x) ids.col(x) = x - 10;  // texton = column - 10
  const StatusOr<std::vector<float>> f = PartsLayoutFeatures(ids, mask, k);
  ASSERT_TRUE(f.ok()) << f.status().ToString();
  ASSERT_EQ(f->size(), 20u * k);
  auto block = [&](int b, int t) { return (*f)[static_cast<size_t>(b) * k + t]; };
  // Coarse top-left: x 10..23, y 20..36 (17 rows each): 1/14 per column.
  for (int t = 0; t < k; ++t) EXPECT_FLOAT_EQ(block(0, t), t < 14 ? 1.0f / 14 : 0.0f) << t;
  // Coarse top-right: x 24..29 with 17 rows each and x 30..49 with 10: 302 pixels.
  for (int t = 0; t < k; ++t) {
    const float expected = t < 14 ? 0.0f : (t < 20 ? 17.0f / 302 : 10.0f / 302);
    EXPECT_FLOAT_EQ(block(1, t), expected) << t;
  }
  // Coarse bottom-left: x 10..23 again; bottom-right: x 24..29 only.
  for (int t = 0; t < k; ++t) {
    EXPECT_FLOAT_EQ(block(2, t), t < 14 ? 1.0f / 14 : 0.0f) << t;
    EXPECT_FLOAT_EQ(block(3, t), t >= 14 && t < 20 ? 1.0f / 6 : 0.0f) << t;
  }
  // Fine row 0, columns 0..3: x 10..16, 17..23, 24..36, 37..49.
  for (int t = 0; t < k; ++t) {
    EXPECT_FLOAT_EQ(block(4, t), t < 7 ? 1.0f / 7 : 0.0f) << t;
    EXPECT_FLOAT_EQ(block(5, t), t >= 7 && t < 14 ? 1.0f / 7 : 0.0f) << t;
    EXPECT_FLOAT_EQ(block(6, t), t >= 14 && t < 27 ? 1.0f / 13 : 0.0f) << t;
    EXPECT_FLOAT_EQ(block(7, t), t >= 27 ? 1.0f / 13 : 0.0f) << t;
  }
}

TEST(PartsLayoutTest, RowsAreCutAtTheCentroidThenHalfWayAndEmptyBlocksAreZero) {
  const int k = 40;
  const cv::Mat mask = PartsMask();
  cv::Mat ids = cv::Mat::zeros(mask.size(), CV_16U);
  for (int y = 20; y < 60; ++y) ids.row(y) = y - 20;  // texton = row - 20
  const StatusOr<std::vector<float>> f = PartsLayoutFeatures(ids, mask, k);
  ASSERT_TRUE(f.ok()) << f.status().ToString();
  auto block = [&](int b, int t) { return (*f)[static_cast<size_t>(b) * k + t]; };
  // Coarse bottom-left: rows 37..59 (23), every one full width.
  for (int t = 0; t < k; ++t) EXPECT_FLOAT_EQ(block(2, t), t >= 17 ? 1.0f / 23 : 0.0f) << t;
  // Fine (row 0, column 0): rows 20..27; (row 3, column 0): rows 48..59.
  for (int t = 0; t < k; ++t) {
    EXPECT_FLOAT_EQ(block(4, t), t < 8 ? 1.0f / 8 : 0.0f) << t;
    EXPECT_FLOAT_EQ(block(16, t), t >= 28 ? 1.0f / 12 : 0.0f) << t;
  }
  // The short right part (x 30..49) ends at row 29: fine column 3 (x 37..49) is empty in
  // rows 2 and 3 (blocks 15 and 19); every other block sums to one.
  for (int b = 0; b < kPartsLayoutBlocks; ++b) {
    float sum = 0;
    for (int t = 0; t < k; ++t) sum += block(b, t);
    EXPECT_NEAR(sum, b == 15 || b == 19 ? 0.0f : 1.0f, 1e-5) << "block " << b;
  }
}

// ---- The whole description ----

TEST(DescribeObjectTest, ShippedDictionaryGivesTheSeeds3181NumbersInGroupOrder) {
  const TextonModel model = ShippedTextons();
  ASSERT_EQ(model.size(), 150);  // seed §4.1.1: k = 150
  const TextonAssigner assigner(model);
  const cv::Mat bgr = TestImage();
  cv::Mat mask = cv::Mat::zeros(bgr.size(), CV_8U);
  cv::ellipse(mask, cv::Point(150, 120), cv::Size(50, 35), 20, 0, 360, cv::Scalar(255), -1);
  const StatusOr<ObjectDescription> d = DescribeObject(bgr, mask, assigner, {});
  ASSERT_TRUE(d.ok()) << d.status().ToString();
  EXPECT_EQ(d->appearance.size(), 151u);
  EXPECT_EQ(d->parts_layout.size(), 3000u);
  EXPECT_EQ(d->shape.size(), 30u);
  EXPECT_EQ(ObjectDescriptionSize(150), 3181);
  const std::vector<float> all = d->Concatenated();
  ASSERT_EQ(all.size(), 3181u);
  EXPECT_TRUE(std::equal(d->appearance.begin(), d->appearance.end(), all.begin()));
  EXPECT_TRUE(std::equal(d->parts_layout.begin(), d->parts_layout.end(), all.begin() + 151));
  EXPECT_TRUE(std::equal(d->shape.begin(), d->shape.end(), all.begin() + 3151));

  // The appearance is the background classifiers' (RegionAppearance's first k + 1 at
  // stride 1) for the same region.
  const cv::Mat features = ComputeFilterBank(ToLab(bgr));
  cv::Mat labels(mask.size(), CV_32S, cv::Scalar(-1));
  labels.setTo(0, mask);
  const cv::Mat region =
      RegionAppearance(labels, 1, ComputeTextonMap(features, assigner, 1), features, assigner);
  int used = 0;
  for (int t = 0; t < 151; ++t) {
    EXPECT_NEAR(d->appearance[t], region.at<float>(0, t), 1e-6) << t;
    used += t < 150 && d->appearance[t] > 0;
  }
  EXPECT_GT(used, 3) << "the test image should show several textons";
}

TEST(DescribeObjectTest, SizesFollowTheDictionary) {
  const TextonAssigner assigner(SmallTextons(5));
  const cv::Mat bgr = TestImage();
  cv::Mat mask = cv::Mat::zeros(bgr.size(), CV_8U);
  mask(cv::Rect(100, 80, 100, 100)) = 255;
  const StatusOr<ObjectDescription> d = DescribeObject(bgr, mask, assigner, {});
  ASSERT_TRUE(d.ok()) << d.status().ToString();
  EXPECT_EQ(d->appearance.size(), 6u);
  EXPECT_EQ(d->parts_layout.size(), 100u);
  EXPECT_EQ(d->shape.size(), 30u);
  EXPECT_EQ(d->Concatenated().size(), static_cast<size_t>(ObjectDescriptionSize(5)));
}

TEST(DescribeObjectTest, BadInputIsAnErrorThatSaysWhat) {
  const TextonAssigner assigner(SmallTextons(5));
  const cv::Mat bgr = TestImage();
  cv::Mat good = cv::Mat::zeros(bgr.size(), CV_8U);
  good(cv::Rect(10, 10, 30, 30)) = 255;
  const ObjectDescriptionOptions options;
  auto expect_error = [&](const cv::Mat& image, const cv::Mat& mask,
                          const ObjectDescriptionOptions& o, const std::string& words) {
    const StatusOr<ObjectDescription> d = DescribeObject(image, mask, assigner, o);
    ASSERT_FALSE(d.ok()) << "expected an error mentioning '" << words << "'";
    EXPECT_EQ(d.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(d.status().message().find(words), std::string::npos) << d.status().message();
  };
  ASSERT_TRUE(DescribeObject(bgr, good, assigner, options).ok());
  expect_error(bgr, cv::Mat::zeros(bgr.size(), CV_8U), options, "no object pixels");
  expect_error(bgr, cv::Mat(), options, "mask is empty");
  expect_error(bgr, good(cv::Rect(0, 0, 100, 100)).clone(), options, "100x100");
  cv::Mat float_mask;
  good.convertTo(float_mask, CV_32F);
  expect_error(bgr, float_mask, options, "CV_8UC1");
  cv::Mat colour_mask;
  cv::cvtColor(good, colour_mask, cv::COLOR_GRAY2BGR);
  expect_error(bgr, colour_mask, options, "CV_8UC1");
  expect_error(cv::Mat(), good, options, "image is empty");
  cv::Mat grey;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  expect_error(grey, good, options, "CV_8UC3");
  ObjectDescriptionOptions bad = options;
  bad.shape_max_side = 0;
  expect_error(bgr, good, bad, "shape_max_side");

  // The pieces check their input too.
  EXPECT_FALSE(SolvePoisson(cv::Mat::zeros(10, 10, CV_8U)).ok());
  EXPECT_FALSE(SolvePoisson(cv::Mat()).ok());
  EXPECT_FALSE(ShapeFeatures(cv::Mat::zeros(10, 10, CV_8U), options).ok());
  EXPECT_FALSE(ComputeShapeMaps(cv::Mat::ones(10, 10, CV_32F), options).ok());
  cv::Mat ids(bgr.size(), CV_16U, cv::Scalar(5));  // texton 5 of 0..4
  const StatusOr<std::vector<float>> out_of_range = AppearanceFeatures(ids, good, 5);
  ASSERT_FALSE(out_of_range.ok());
  EXPECT_NE(out_of_range.status().message().find("not below the texton count"), std::string::npos);
  EXPECT_FALSE(PartsLayoutFeatures(ids, good, 5).ok());
  EXPECT_FALSE(PartsLayoutFeatures(cv::Mat(bgr.size(), CV_32S, cv::Scalar(0)), good, 5).ok());
  EXPECT_FALSE(
      DescribeObjectInFeatures(cv::Mat(bgr.size(), CV_32FC3), good, assigner, options).ok());
}

}  // namespace
}  // namespace placerec
