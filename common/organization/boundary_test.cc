#include "common/organization/boundary.h"

#include <cmath>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core/persistence.hpp>
#include <opencv2/imgproc.hpp>

#include "common/organization/filter_bank.h"

namespace placerec {
namespace {

// Feature layout (boundary.h): 72 channel differences (per distance: 12 channels x largest,
// smallest), 6 colour differences, 20 bank values, 2 gradient magnitudes, the height.
constexpr int kColourOffset = 72;
constexpr int kBankOffset = 78;
constexpr int kGradientOffset = 98;
constexpr int kHeightOffset = 100;

cv::Mat LabOf(const cv::Mat& bgr) {
  cv::Mat f;
  bgr.convertTo(f, CV_32F, 1.0 / 255.0);
  cv::Mat lab;
  cv::cvtColor(f, lab, cv::COLOR_BGR2Lab);
  return lab;
}

// A 60 x 40 image, dark on the left of column 30 and bright on the right, with mild noise.
cv::Mat StepImage(int seed) {
  cv::Mat bgr(40, 60, CV_8UC3);
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.0f, 3.0f);
  for (int y = 0; y < bgr.rows; ++y) {
    for (int x = 0; x < bgr.cols; ++x) {
      const float base = x < 30 ? 60.0f : 190.0f;
      for (int c = 0; c < 3; ++c) {
        bgr.at<cv::Vec3b>(y, x)[c] = cv::saturate_cast<uchar>(base + 10 * c + noise(rng));
      }
    }
  }
  return bgr;
}

TEST(BoundaryFeaturesTest, ConstantImageHasNoDifferencesAndItsOwnBankValues) {
  const cv::Mat lab = LabOf(cv::Mat(30, 40, CV_8UC3, cv::Scalar(40, 120, 200)));
  const cv::Mat bank = ComputeFilterBank(lab);
  float f[kBoundaryFeatures];
  for (const cv::Point p : {cv::Point(0, 0), cv::Point(20, 15), cv::Point(39, 29)}) {
    BoundaryPixelFeatures(bank, p.x, p.y, f);
    for (int i = 0; i < kBankOffset; ++i) EXPECT_NEAR(f[i], 0.0f, 1e-3) << "feature " << i;
    const float* b = bank.ptr<float>(p.y) + p.x * kTextonFeatureSize;
    for (int c = 0; c < kTextonFeatureSize; ++c) EXPECT_FLOAT_EQ(f[kBankOffset + c], b[c]);
    EXPECT_NEAR(f[kGradientOffset], 0.0f, 1e-3);
    EXPECT_NEAR(f[kGradientOffset + 1], 0.0f, 1e-3);
    EXPECT_FLOAT_EQ(f[kHeightOffset], p.y / 29.0f);
  }
}

// Beside a vertical step the horizontal difference is large and the vertical one is zero, so
// the largest over directions is large and the smallest small; far from it both vanish.
TEST(BoundaryFeaturesTest, StepEdgeShowsAcrossButNotAlongIt) {
  cv::Mat bgr(40, 60, CV_8UC3, cv::Scalar(60, 60, 60));
  bgr.colRange(30, 60).setTo(cv::Scalar(190, 190, 190));
  const cv::Mat bank = ComputeFilterBank(LabOf(bgr));
  float at_edge[kBoundaryFeatures];
  float far[kBoundaryFeatures];
  BoundaryPixelFeatures(bank, 29, 20, at_edge);
  BoundaryPixelFeatures(bank, 5, 20, far);
  // Channel 0 (G1.L) at distance 1: largest, smallest.
  EXPECT_GT(at_edge[0], 10.0f);
  EXPECT_NEAR(at_edge[1], 0.0f, 1e-3);
  // Delta E on G1 at distance 1, G2 at 3, G4 at 6: largest.
  EXPECT_GT(at_edge[kColourOffset], 10.0f);
  EXPECT_GT(at_edge[kColourOffset + 2], 10.0f);
  EXPECT_GT(at_edge[kColourOffset + 4], 10.0f);
  EXPECT_GT(at_edge[kGradientOffset], 1.0f);
  for (int i = 0; i < kBankOffset; ++i) EXPECT_NEAR(far[i], 0.0f, 1e-2) << "feature " << i;
}

TEST(BoundaryFeaturesTest, CrackPixelsAreBothSidesOfEveryLabelChange) {
  cv::Mat labels(4, 6, CV_32S, cv::Scalar(0));
  labels.colRange(3, 6).setTo(1);
  labels.at<int>(0, 0) = 2;
  const cv::Mat mask = CrackPixels(labels);
  const int expected[4][6] = {
      {1, 1, 1, 1, 0, 0}, {1, 0, 1, 1, 0, 0}, {0, 0, 1, 1, 0, 0}, {0, 0, 1, 1, 0, 0}};
  for (int y = 0; y < 4; ++y) {
    for (int x = 0; x < 6; ++x) EXPECT_EQ(mask.at<uint8_t>(y, x), expected[y][x]) << x << "," << y;
  }
}

TEST(BoundaryFeaturesTest, CrackPixelsCanIgnoreUnlabelledPixels) {
  // Objects 1 and 2 meet in column 2/3; unlabelled (0) pixels border both.
  cv::Mat labels(3, 6, CV_32S, cv::Scalar(1));
  labels.colRange(3, 6).setTo(2);
  labels.row(2).setTo(0);
  labels.at<int>(0, 0) = 0;
  const cv::Mat mask = CrackPixels(labels, /*ignore_unlabelled=*/true);
  const int expected[3][6] = {{0, 0, 1, 1, 0, 0}, {0, 0, 1, 1, 0, 0}, {0, 0, 0, 0, 0, 0}};
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 6; ++x) EXPECT_EQ(mask.at<uint8_t>(y, x), expected[y][x]) << x << "," << y;
  }
  // Without the flag the unlabelled pixels' borders are cracks too.
  EXPECT_EQ(CrackPixels(labels).at<uint8_t>(2, 0), 1);
  EXPECT_EQ(CrackPixels(labels).at<uint8_t>(0, 1), 1);
}

// Training samples from step images: pixels beside the step are boundaries, the rest not.
void StepSamples(int images, cv::Mat* features, std::vector<int>* labels) {
  float f[kBoundaryFeatures];
  for (int i = 0; i < images; ++i) {
    const cv::Mat bank = ComputeFilterBank(LabOf(StepImage(i)));
    for (int y = 2; y < 38; y += 3) {
      for (int x = 2; x < 58; x += 2) {
        BoundaryPixelFeatures(bank, x, y, f);
        features->push_back(cv::Mat(1, kBoundaryFeatures, CV_32F, f));
        labels->push_back(x == 29 || x == 30 ? 1 : 0);
      }
    }
  }
}

BoundaryModel TrainedOnSteps() {
  cv::Mat features;
  std::vector<int> labels;
  StepSamples(4, &features, &labels);
  BoundaryModel::TrainingOptions options;
  options.weak_count = 20;
  options.max_depth = 2;
  return BoundaryModel::Train(features, labels, {}, options);
}

TEST(BoundaryModelTest, LearnsTheStepAndScoresOnlyMaskedPixels) {
  const BoundaryModel model = TrainedOnSteps();
  ASSERT_FALSE(model.empty());
  const cv::Mat bank = ComputeFilterBank(LabOf(StepImage(99)));
  cv::Mat mask(bank.size(), CV_8U, cv::Scalar(0));
  mask.col(30).setTo(1);
  mask.col(10).setTo(1);
  const cv::Mat scores = model.ScoreMap(bank, mask);
  ASSERT_EQ(scores.type(), CV_32F);
  float f[kBoundaryFeatures];
  for (int y = 0; y < bank.rows; ++y) {
    EXPECT_GT(scores.at<float>(y, 30), 0.0f) << "row " << y;
    EXPECT_LT(scores.at<float>(y, 10), 0.0f) << "row " << y;
    EXPECT_EQ(scores.at<float>(y, 45), 0.0f);  // not masked
    BoundaryPixelFeatures(bank, 30, y, f);
    EXPECT_FLOAT_EQ(scores.at<float>(y, 30), static_cast<float>(model.Score(f)));
  }
}

TEST(BoundaryModelTest, SaveLoadRoundTripScoresAlike) {
  const BoundaryModel model = TrainedOnSteps();
  const std::string dir = ::testing::TempDir() + "/boundary_round_trip";
  std::filesystem::create_directories(dir);
  ASSERT_TRUE(model.Save(dir).ok());
  EXPECT_FALSE(std::filesystem::exists(dir + "/.writing." + BoundaryModel::kFileName));
  const StatusOr<BoundaryModel> loaded = BoundaryModel::Load(dir);
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  cv::Mat features;
  std::vector<int> labels;
  StepSamples(1, &features, &labels);
  for (int r = 0; r < features.rows; ++r) {
    EXPECT_DOUBLE_EQ(loaded->Score(features.ptr<float>(r)), model.Score(features.ptr<float>(r)));
  }
}

TEST(BoundaryModelTest, MissingFileIsNotFoundAndForeignFileIsRejected) {
  const StatusOr<BoundaryModel> missing = BoundaryModel::Load("/nonexistent/placerec");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), StatusCode::kNotFound);
  const std::string dir = ::testing::TempDir() + "/boundary_foreign";
  std::filesystem::create_directories(dir);
  {
    cv::FileStorage fs(dir + "/" + BoundaryModel::kFileName, cv::FileStorage::WRITE);
    fs << "format_version" << 1 << "features" << 7;
  }
  const StatusOr<BoundaryModel> foreign = BoundaryModel::Load(dir);
  ASSERT_FALSE(foreign.ok());
  EXPECT_EQ(foreign.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(foreign.status().message().find("placerec-train boundary"), std::string::npos);
}

TEST(BoundaryModelTest, DefaultTrainingOptionsPassAndBadOnesFail) {
  BoundaryModel::TrainingOptions options;
  std::string error;
  EXPECT_TRUE(options.Check(&error)) << error;
  options.max_depth = 0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_FALSE(error.empty());
}

}  // namespace
}  // namespace placerec
