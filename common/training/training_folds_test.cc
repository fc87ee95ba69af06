// Cross-fitting folds of placerec-train (labelled_dataset.h, grouping_training.h).
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/training/grouping_training.h"
#include "common/training/labelled_dataset.h"

namespace placerec {
namespace {

TEST(FoldTest, ParsesIndexOverCount) {
  StatusOr<Fold> fold = ParseFold("1/3");
  ASSERT_TRUE(fold.ok()) << fold.status().ToString();
  EXPECT_EQ(fold->index, 1);
  EXPECT_EQ(fold->count, 3);
  EXPECT_EQ(fold->ToString(), "1/3");
  StatusOr<Fold> none = ParseFold("");
  ASSERT_TRUE(none.ok());
  EXPECT_TRUE(none->empty());
  EXPECT_EQ(none->ToString(), "");
}

TEST(FoldTest, RejectsMalformedFolds) {
  for (const std::string text : {"3/3", "0/1", "-1/2", "a/2", "1/2x", "1", "/2", "1/"}) {
    StatusOr<Fold> fold = ParseFold(text);
    EXPECT_FALSE(fold.ok()) << text;
    if (!fold.ok()) {
      EXPECT_NE(fold.status().ToString().find("I/K"), std::string::npos);
    }
  }
}

TEST(FoldTest, FoldsAreContiguousCoverEveryImageAndDifferByAtMostOne) {
  for (const size_t total : {2u, 7u, 10u, 422u}) {
    for (int count = 2; count <= 5 && static_cast<size_t>(count) <= total; ++count) {
      std::vector<int> sizes(static_cast<size_t>(count), 0);
      int previous = 0;
      for (size_t p = 0; p < total; ++p) {
        const int fold = FoldOf(p, total, count);
        ASSERT_GE(fold, previous) << "folds must be contiguous";
        ASSERT_LT(fold, count);
        previous = fold;
        ++sizes[static_cast<size_t>(fold)];
      }
      const auto [smallest, largest] = std::minmax_element(sizes.begin(), sizes.end());
      EXPECT_GE(*smallest, 1) << total << " images, " << count << " folds";
      EXPECT_LE(*largest - *smallest, 1) << total << " images, " << count << " folds";
    }
  }
}

// Grouping training refuses cross-fit directories whose background models did not leave out
// the fold they would describe, and names the command that makes the right ones.
TEST(FoldTest, CrossFitChecksEachDirectoryLeftOutItsFold) {
  namespace fs = std::filesystem;
  const fs::path root =
      fs::path(::testing::TempDir()) / ("placerec_folds_" + std::to_string(getpid()));
  fs::create_directories(root / "data");
  std::ofstream(root / "data" / "train.txt") << "a\nb\nc\nd\n";
  for (int k = 0; k < 2; ++k) {
    fs::create_directories(root / ("fold" + std::to_string(k)));
    // Both claim fold 0/2: the second is wrong.
    std::ofstream(root / ("fold" + std::to_string(k)) / "manifest.json")
        << R"({"data": {"dataset": "data", "split": "train", "holdout_first_images": 1,
                        "left_out_fold": "0/2"}})";
  }
  GroupingTrainingConfig config;
  config.dataset = (root / "data").string();
  config.holdout = 1;
  config.out = (root / "out").string();
  config.progress = false;
  config.cross_fit = {(root / "fold0").string(), (root / "fold1").string()};
  StatusOr<nlohmann::json> result = TrainGroupingModel(config);
  ASSERT_FALSE(result.ok());
  const std::string message = result.status().ToString();
  EXPECT_NE(message.find("fold1"), std::string::npos) << message;
  EXPECT_NE(message.find("--holdout 1 --leave-out-fold 1/2"), std::string::npos) << message;
  EXPECT_FALSE(fs::exists(root / "out" / "grouping.yml.gz"));

  config.cross_fit = {(root / "fold0").string()};
  EXPECT_FALSE(TrainGroupingModel(config).ok()) << "one directory is no cross-fitting";
  fs::remove_all(root);
}

}  // namespace
}  // namespace placerec
