// Tests of the object-classification training bookkeeping (placerec-train objects,
// placerec-eval classify): the region accuracy and confusion counts, the ablation's variants,
// and the ground-truth segments of a small dataset written on the fly (which objects are kept,
// their classes, the per-class cap and the errors for a missing layer or an unknown class).

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/training/object_training.h"

namespace placerec {
namespace {

TEST(ObjectTrainingTest, DefaultsPassCheck) {
  std::string error;
  EXPECT_TRUE(TruthSegmentOptions().Check(&error)) << error;
  ObjectTrainingConfig config;
  config.dataset = "d";
  config.out = "o";
  EXPECT_TRUE(config.Check(&error)) << error;
  config.min_class_segments = 1;
  EXPECT_FALSE(config.Check(&error));
  EXPECT_NE(error.find("min_class_segments"), std::string::npos);
}

TEST(ObjectTrainingTest, VariantsFollowTheSeedsAblation) {
  const std::vector<ObjectModelVariant>& variants = ObjectModelVariants();
  ASSERT_EQ(variants.size(), 5u);
  EXPECT_EQ(variants[0].name, "all");
  EXPECT_TRUE(variants[0].select);
  EXPECT_FALSE(variants[4].select);
  const std::vector<FeatureGroup> shape = VariantGroups(variants[3], 150, 50);
  ASSERT_EQ(shape.size(), 2u);
  EXPECT_EQ(shape[0].name, "appearance");
  EXPECT_EQ(shape[1].name, "shape");
  EXPECT_EQ(shape[1].begin, 3151);
  EXPECT_EQ(VariantGroups(variants[0], 150, 50).size(), 3u);
}

TEST(ObjectTrainingTest, AccuracyCountsPerTrueClass) {
  ClassificationAccuracy accuracy({"car", "building", "body"});
  accuracy.Add(0, 0);
  accuracy.Add(0, 0);
  accuracy.Add(0, 1);
  accuracy.Add(0, 0);
  accuracy.Add(1, 1);
  accuracy.Add(1, -1);  // no decision
  EXPECT_DOUBLE_EQ(accuracy.Accuracy(0), 75.0);
  EXPECT_DOUBLE_EQ(accuracy.Accuracy(1), 50.0);
  EXPECT_TRUE(std::isnan(accuracy.Accuracy(2)));
  EXPECT_DOUBLE_EQ(accuracy.MeanAccuracy(), 62.5);
  EXPECT_DOUBLE_EQ(accuracy.MeanAccuracy({false, true, true}), 50.0);
  const nlohmann::json j = accuracy.ToJson();
  EXPECT_DOUBLE_EQ(j["per_class_accuracy"]["car"].get<double>(), 75.0);
  EXPECT_FALSE(j["per_class_accuracy"].contains("body"));
  EXPECT_EQ(j["confusion"]["car"]["building"].get<int>(), 1);
  EXPECT_EQ(j["confusion"]["building"]["none"].get<int>(), 1);
  EXPECT_EQ(j["total_segments"].get<int>(), 6);
  EXPECT_DOUBLE_EQ(j["overall_accuracy"].get<double>(), 400.0 / 6.0);
}

// A dataset of two 80x60 images: image a holds a car (object 1, 40x30 pixels), a tiny
// building (object 2, 5x5) and a void object (3); image b a car (1) and a building (2), both
// large.
std::string WriteTinyDataset() {
  const std::string dir = ::testing::TempDir() + "/placerec_object_training_test";
  std::filesystem::remove_all(dir);
  for (const char* sub : {"images", "classes", "objects"}) {
    std::filesystem::create_directories(dir + "/" + sub);
  }
  std::ofstream(dir + "/classes.txt") << "0 void\n1 building\n2 car\n";
  std::ofstream(dir + "/train.txt") << "a\nb\n";
  cv::RNG rng(5);
  for (const std::string id : {"a", "b"}) {
    cv::Mat image(60, 80, CV_8UC3);
    rng.fill(image, cv::RNG::UNIFORM, 0, 255);
    cv::Mat classes = cv::Mat::zeros(60, 80, CV_8U);
    cv::Mat objects = cv::Mat::zeros(60, 80, CV_8U);
    objects(cv::Rect(0, 0, 40, 30)) = 1;
    classes(cv::Rect(0, 0, 40, 30)) = 2;
    if (id == "a") {
      objects(cv::Rect(50, 40, 5, 5)) = 2;
      classes(cv::Rect(50, 40, 5, 5)) = 1;
      objects(cv::Rect(60, 0, 20, 20)) = 3;  // class 0: void
    } else {
      objects(cv::Rect(40, 30, 40, 30)) = 2;
      classes(cv::Rect(40, 30, 40, 30)) = 1;
    }
    cv::imwrite(dir + "/images/" + id + ".png", image);
    cv::imwrite(dir + "/classes/" + id + ".png", classes);
    cv::imwrite(dir + "/objects/" + id + ".png", objects);
  }
  return dir;
}

TextonModel TinyTextons() {
  TextonModel model;
  model.mean = cv::Mat::zeros(1, kTextonFeatureSize, CV_32F);
  model.inv_std = cv::Mat::ones(1, kTextonFeatureSize, CV_32F);
  model.centres = cv::Mat(4, kTextonFeatureSize, CV_32F);
  cv::RNG(1).fill(model.centres, cv::RNG::UNIFORM, -1, 1);
  return model;
}

TEST(ObjectTrainingTest, DescribesTheGroundTruthObjects) {
  const std::string dir = WriteTinyDataset();
  StatusOr<ClassTable> table = ReadClassTable(dir);
  ASSERT_TRUE(table.ok());
  const TextonAssigner textons(TinyTextons());
  TruthSegmentOptions options;  // min_object_pixels 100: the 5x5 building is left out
  StatusOr<DescribedSegments> segments =
      DescribeTruthSegments(dir, "train", *table, textons, {}, options, false);
  ASSERT_TRUE(segments.ok()) << segments.status().ToString();
  ASSERT_EQ(segments->size(), 3);
  EXPECT_EQ(segments->features.cols, ObjectDescriptionSize(4));
  EXPECT_EQ(segments->class_ids, (std::vector<int>{2, 2, 1}));
  EXPECT_EQ(segments->images, (std::vector<std::string>{"a", "b", "b"}));
  EXPECT_EQ(segments->objects, (std::vector<int>{1, 1, 2}));
  // The car's centroid height (last appearance number): rows 0..29 of 60, (14.5 + 0.5) / 60.
  EXPECT_NEAR(segments->features.at<float>(0, 4), 15.0 / 60.0, 1e-6);

  // Excluding cars, and a cap of one segment per class.
  StatusOr<DescribedSegments> no_cars =
      DescribeTruthSegments(dir, "train", *table, textons, {"car"}, options, false);
  ASSERT_TRUE(no_cars.ok());
  EXPECT_EQ(no_cars->class_ids, (std::vector<int>{1}));
  options.max_segments_per_class = 1;
  StatusOr<DescribedSegments> capped =
      DescribeTruthSegments(dir, "train", *table, textons, {}, options, false);
  ASSERT_TRUE(capped.ok());
  EXPECT_EQ(capped->size(), 2);

  // Errors: an unknown class to exclude, a missing split, a missing objects layer.
  options = TruthSegmentOptions();
  EXPECT_FALSE(
      DescribeTruthSegments(dir, "train", *table, textons, {"horse"}, options, false).ok());
  EXPECT_FALSE(DescribeTruthSegments(dir, "test", *table, textons, {}, options, false).ok());
  std::filesystem::remove(dir + "/objects/b.png");
  const Status missing =
      DescribeTruthSegments(dir, "train", *table, textons, {}, options, false).status();
  EXPECT_FALSE(missing.ok());
  EXPECT_NE(missing.message().find("objects"), std::string::npos);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace placerec
