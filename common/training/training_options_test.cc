// The trainers' configs (background, boundary and grouping training) validate their fields:
// the defaults with a dataset and an output directory pass, and one bad value at a time fails
// with a message that names the field.
#include <limits>
#include <string>
#include <type_traits>

#include <gtest/gtest.h>

#include "common/training/background_training.h"
#include "common/training/boundary_training.h"
#include "common/training/grouping_training.h"
#include "common/training/labelled_dataset.h"

namespace placerec {
namespace {

template <typename Config>
Config WithPaths() {
  Config config;
  if constexpr (std::is_same_v<Config, BackgroundTrainingConfig>) {
    config.datasets = {"data/stanford_background"};
  } else {
    config.dataset = "data/stanford_background";
  }
  config.out = "models";
  return config;
}

// Check fails and its message names `field`.
template <typename Config>
void ExpectFails(const Config& config, const std::string& field) {
  std::string error;
  EXPECT_FALSE(config.Check(&error)) << field;
  EXPECT_NE(error.find(field), std::string::npos) << "'" << error << "' does not name " << field;
}

TEST(FoldCheckTest, EmptyAndParsedFoldsPassOthersFail) {
  std::string error;
  EXPECT_TRUE(Fold().Check(&error));
  EXPECT_TRUE(ParseFold("1/3")->Check(&error));
  EXPECT_FALSE((Fold{2, 2}).Check(&error));
  EXPECT_NE(error.find("leave_out_fold"), std::string::npos);
  EXPECT_FALSE((Fold{0, 1}).Check(&error));
  EXPECT_FALSE((Fold{-1, 3}).Check(&error));
}

TEST(BackgroundTrainingConfigTest, DefaultsPass) {
  std::string error;
  EXPECT_TRUE(WithPaths<BackgroundTrainingConfig>().Check(&error)) << error;
}

TEST(BackgroundTrainingConfigTest, OneBadValueFailsNamingTheField) {
  BackgroundTrainingConfig config = WithPaths<BackgroundTrainingConfig>();
  config.datasets.clear();
  ExpectFails(config, "datasets");
  config = WithPaths<BackgroundTrainingConfig>();
  config.datasets.push_back("");
  ExpectFails(config, "datasets");
  config = WithPaths<BackgroundTrainingConfig>();
  config.out.clear();
  ExpectFails(config, "out");
  config = WithPaths<BackgroundTrainingConfig>();
  config.split.clear();
  ExpectFails(config, "split");
  config = WithPaths<BackgroundTrainingConfig>();
  config.pixels_per_image = 0;
  ExpectFails(config, "pixels_per_image");
  config = WithPaths<BackgroundTrainingConfig>();
  config.min_labelled_fraction = 1.5;
  ExpectFails(config, "min_labelled_fraction");
  config = WithPaths<BackgroundTrainingConfig>();
  config.min_region_pixels = 0;
  ExpectFails(config, "min_region_pixels");
  config = WithPaths<BackgroundTrainingConfig>();
  config.holdout = -1;
  ExpectFails(config, "holdout");
  config = WithPaths<BackgroundTrainingConfig>();
  config.check_images = -1;
  ExpectFails(config, "check_images");
  config = WithPaths<BackgroundTrainingConfig>();
  config.area_weight_power = std::numeric_limits<double>::quiet_NaN();
  ExpectFails(config, "area_weight_power");
  config = WithPaths<BackgroundTrainingConfig>();
  config.structured_classes = {"building", ""};
  ExpectFails(config, "structured_classes");
  config = WithPaths<BackgroundTrainingConfig>();
  config.leave_out_fold = Fold{3, 2};
  ExpectFails(config, "leave_out_fold");
  config = WithPaths<BackgroundTrainingConfig>();
  config.organizer.texton_stride = 0;
  ExpectFails(config, "texton_stride");
}

TEST(BoundaryTrainingConfigTest, DefaultsPass) {
  std::string error;
  EXPECT_TRUE(WithPaths<BoundaryTrainingConfig>().Check(&error)) << error;
}

TEST(BoundaryTrainingConfigTest, OneBadValueFailsNamingTheField) {
  BoundaryTrainingConfig config = WithPaths<BoundaryTrainingConfig>();
  config.dataset.clear();
  ExpectFails(config, "dataset");
  config = WithPaths<BoundaryTrainingConfig>();
  config.out.clear();
  ExpectFails(config, "out");
  config = WithPaths<BoundaryTrainingConfig>();
  config.holdout = -2;
  ExpectFails(config, "holdout");
  config = WithPaths<BoundaryTrainingConfig>();
  config.samples_per_image = 0;
  ExpectFails(config, "samples_per_image");
  config = WithPaths<BoundaryTrainingConfig>();
  config.negative_distance = config.positive_distance;
  ExpectFails(config, "negative_distance");
  config = WithPaths<BoundaryTrainingConfig>();
  config.positive_distance = -1.0;
  ExpectFails(config, "positive_distance");
  config = WithPaths<BoundaryTrainingConfig>();
  config.leave_out_fold = Fold{0, 1};
  ExpectFails(config, "leave_out_fold");
  config = WithPaths<BoundaryTrainingConfig>();
  config.organizer.texton_stride = 9;
  ExpectFails(config, "texton_stride");
}

TEST(GroupingTrainingConfigTest, DefaultsPass) {
  std::string error;
  EXPECT_TRUE(WithPaths<GroupingTrainingConfig>().Check(&error)) << error;
}

TEST(GroupingTrainingConfigTest, OneBadValueFailsNamingTheField) {
  GroupingTrainingConfig config = WithPaths<GroupingTrainingConfig>();
  config.dataset.clear();
  ExpectFails(config, "dataset");
  config = WithPaths<GroupingTrainingConfig>();
  config.out.clear();
  ExpectFails(config, "out");
  config = WithPaths<GroupingTrainingConfig>();
  config.holdout = -1;
  ExpectFails(config, "holdout");
  config = WithPaths<GroupingTrainingConfig>();
  config.levels = -1;
  ExpectFails(config, "levels");
  config = WithPaths<GroupingTrainingConfig>();
  config.level_fraction = 0.0;
  ExpectFails(config, "level_fraction");
  config = WithPaths<GroupingTrainingConfig>();
  config.min_purity = 1.5;
  ExpectFails(config, "min_purity");
  config = WithPaths<GroupingTrainingConfig>();
  config.policy_threshold = std::numeric_limits<double>::infinity();
  ExpectFails(config, "policy_threshold");
  config = WithPaths<GroupingTrainingConfig>();
  config.max_pairs = -1;
  ExpectFails(config, "max_pairs");
  config = WithPaths<GroupingTrainingConfig>();
  config.features = kMergeFeatures + 1;
  ExpectFails(config, "features");
  config = WithPaths<GroupingTrainingConfig>();
  config.cross_fit = {"models_0"};
  ExpectFails(config, "cross_fit");
  config = WithPaths<GroupingTrainingConfig>();
  config.organizer.background_smoothing = 2.0;
  ExpectFails(config, "background_smoothing");
}

}  // namespace
}  // namespace placerec
