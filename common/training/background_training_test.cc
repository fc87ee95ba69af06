// placerec-train background (background_training.h) replaces a models directory only when the
// whole training has succeeded, and refuses training data it cannot learn from with an error.
// Runs on three real stanford_background images with a tiny configuration (8 textons, 5 trees).
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "common/training/background_training.h"
#include "common/util/paths.h"

namespace placerec {
namespace {

namespace fs = std::filesystem;

// Two training images with all five background classes, one test image.
const char* const kTrain[] = {"2000042", "3001336"};
const char* const kTest = "0000059";
// camvid street scenes (sky, road, pavement, tree, buildings, cars): one to train, one to test.
const char* const kCamvidTrain = "0001TP_006690";
const char* const kCamvidTest = "0001TP_008550";

std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

class BackgroundTrainingTest : public ::testing::Test {
 protected:
  void SetUp() override {
    source_ = DataDir("", PLACEREC_DEFAULT_DATA_DIR);
    const std::string source = source_ + "/stanford_background";
    if (!fs::exists(source + "/images/" + std::string(kTest) + ".jpg")) {
      GTEST_SKIP() << "needs " << source << " (the shared evaluation data); set PLACEREC_DATA";
    }
    root_ = fs::path(::testing::TempDir()) / ("placerec_bgtrain_" + std::to_string(getpid()));
    fs::remove_all(root_);
    data_ = root_ / "data";
    CopyDataset(source, {kTrain[0], kTrain[1]}, {kTest}, data_);

    config_.datasets = {data_.string()};
    config_.out = (root_ / "models").string();
    config_.textons.k = 8;
    config_.pixels_per_image = 100;
    config_.boost.weak_count = 5;
    config_.structured_classes = {};
    config_.check_images = 1;
    config_.progress = false;
  }
  void TearDown() override {
    if (!root_.empty() && !HasFailure()) fs::remove_all(root_);
  }

  // Old model files whose survival shows that a failed run changed nothing.
  void PlantOldModels() {
    fs::create_directories(config_.out);
    std::ofstream(fs::path(config_.out) / "textons.yml") << "old textons\n";
    std::ofstream(fs::path(config_.out) / "manifest.json") << "old manifest\n";
  }
  void ExpectOldModelsUntouched() {
    EXPECT_EQ(ReadText(fs::path(config_.out) / "textons.yml"), "old textons\n");
    EXPECT_EQ(ReadText(fs::path(config_.out) / "manifest.json"), "old manifest\n");
    int entries = 0;
    for (const auto& entry : fs::directory_iterator(config_.out)) {
      ++entries;
      EXPECT_EQ(entry.path().filename().string().rfind(".training", 0), std::string::npos)
          << "staging directory left behind: " << entry.path();
    }
    EXPECT_EQ(entries, 2);
  }

  // A small copy of the labelled dataset at `source` in `to`: classes.txt and the listed
  // images with their ground truth, in train.txt and test.txt.
  static void CopyDataset(const std::string& source, const std::vector<std::string>& train,
                          const std::vector<std::string>& test, const fs::path& to) {
    for (const char* layer : {"images", "classes", "objects"}) fs::create_directories(to / layer);
    fs::copy_file(source + "/classes.txt", to / "classes.txt");
    for (const auto& [split, ids] : {std::pair{"train", &train}, std::pair{"test", &test}}) {
      std::ofstream list(to / (std::string(split) + ".txt"));
      for (const std::string& id : *ids) {
        fs::copy_file(source + "/images/" + id + ".jpg", to / "images" / (id + ".jpg"));
        for (const char* layer : {"classes", "objects"}) {
          fs::copy_file(source + "/" + layer + "/" + id + ".png", to / layer / (id + ".png"));
        }
        list << id << "\n";
      }
    }
  }

  std::string source_;
  fs::path root_;
  fs::path data_;
  BackgroundTrainingConfig config_;
};

TEST_F(BackgroundTrainingTest, SuccessReplacesTheModelsAndLeavesNoStaging) {
  PlantOldModels();
  config_.command_line = "placerec-train background --textons 8 --weak-count 5";
  StatusOr<nlohmann::json> manifest = TrainBackgroundModels(config_);
  ASSERT_TRUE(manifest.ok()) << manifest.status().ToString();
  const fs::path out(config_.out);
  EXPECT_NE(ReadText(out / "textons.yml"), "old textons\n");
  const nlohmann::json written = nlohmann::json::parse(ReadText(out / "manifest.json"));
  EXPECT_EQ(written, *manifest);
  EXPECT_EQ(written.value("command", ""), config_.command_line);  // as typed, to retrain
  for (const char* file : {"background.yml", "background_sky.yml.gz", "background_water.yml.gz",
                           "check_sample.yml.gz"}) {
    EXPECT_TRUE(fs::exists(out / file)) << file;
    EXPECT_TRUE(written.at("file_bytes").contains(file)) << file;
  }
  for (const auto& entry : fs::directory_iterator(out)) {
    EXPECT_EQ(entry.path().filename().string().rfind(".training", 0), std::string::npos)
        << entry.path();
  }
}

// A broken evaluation image is found before training starts, not after it.
TEST_F(BackgroundTrainingTest, BrokenEvaluationImageIsAnErrorBeforeTrainingAndChangesNothing) {
  PlantOldModels();
  std::ofstream(data_ / "images" / (std::string(kTest) + ".jpg")) << "not a jpeg";
  StatusOr<nlohmann::json> manifest = TrainBackgroundModels(config_);
  ASSERT_FALSE(manifest.ok());
  const std::string message = manifest.status().ToString();
  EXPECT_NE(message.find(std::string(kTest) + ".jpg"), std::string::npos) << message;
  EXPECT_NE(message.find("--eval-split"), std::string::npos) << message;
  ExpectOldModelsUntouched();
}

// Training images without a class's regions: a clear error (it was a CHECK failure that killed
// the process) after the textons were computed, and the old models stay.
TEST_F(BackgroundTrainingTest, TrainingImagesWithoutAClassAreAnErrorAndChangeNothing) {
  PlantOldModels();
  // The test image has neither grass nor water; grass is the first class checked.
  std::ofstream(data_ / "train.txt") << kTest << "\n";
  StatusOr<nlohmann::json> manifest = TrainBackgroundModels(config_);
  ASSERT_FALSE(manifest.ok());
  const std::string message = manifest.status().ToString();
  EXPECT_NE(message.find("no training regions of class grass"), std::string::npos) << message;
  ExpectOldModelsUntouched();
}

// Several datasets: their training images are pooled (camvid's pavement counting as road), each
// test split is scored on its own, and the manifest says what came from where.
TEST_F(BackgroundTrainingTest, SeveralDatasetsPoolTheirTrainingImagesAndScoreEachTestSplit) {
  const std::string camvid_source = source_ + "/camvid";
  if (!fs::exists(camvid_source + "/images/" + std::string(kCamvidTest) + ".jpg")) {
    GTEST_SKIP() << "needs " << camvid_source;
  }
  const fs::path camvid = root_ / "camvid";
  CopyDataset(camvid_source, {kCamvidTrain}, {kCamvidTest}, camvid);
  config_.datasets = {data_.string(), camvid.string() + "/"};
  StatusOr<nlohmann::json> manifest = TrainBackgroundModels(config_);
  ASSERT_TRUE(manifest.ok()) << manifest.status().ToString();
  const nlohmann::json& data = manifest->at("data");
  EXPECT_EQ(data.at("dataset"), "data,camvid");
  EXPECT_EQ(data.at("images"), 3);
  EXPECT_EQ(data.at("images_per_dataset"), (nlohmann::json{{"data", 2}, {"camvid", 1}}));
  const nlohmann::json& by_dataset = manifest->at("accuracy_by_dataset");
  ASSERT_TRUE(by_dataset.contains("data") && by_dataset.contains("camvid")) << by_dataset.dump();
  EXPECT_EQ(manifest->at("accuracy"), by_dataset.at("data"));
  const nlohmann::json& camvid_regions = by_dataset.at("camvid").at("ground_truth_objects");
  // Road and pavement regions are both road; camvid has no grass or water.
  const nlohmann::json& decided = camvid_regions.at("decisions_by_true_class");
  EXPECT_TRUE(decided.contains("pavement")) << decided.dump();
  int road_and_pavement = 0;
  for (const char* name : {"road", "pavement"}) {
    if (!decided.contains(name)) continue;
    for (const auto& [to, count] : decided.at(name).items()) road_and_pavement += count.get<int>();
  }
  EXPECT_EQ(camvid_regions.at("classes").at("road").at("regions"), road_and_pavement);
  EXPECT_GT(road_and_pavement, 0);
  EXPECT_EQ(camvid_regions.at("classes").at("grass").at("regions"), 0);
  EXPECT_EQ(manifest->at("check_sample").at("dataset"), "data");
}

// --textons-file: the dictionary is read, not learned, and copied beside the classifiers.
TEST_F(BackgroundTrainingTest, TextonsFromAFileAreKeptAsTheyAre) {
  StatusOr<nlohmann::json> first = TrainBackgroundModels(config_);
  ASSERT_TRUE(first.ok()) << first.status().ToString();
  BackgroundTrainingConfig again = config_;
  again.out = (root_ / "again").string();
  again.textons_file = config_.out + "/textons.yml";
  again.seed = config_.seed + 1;  // other pixels would give other textons if k-means ran
  again.textons.seed = again.seed;
  StatusOr<nlohmann::json> second = TrainBackgroundModels(again);
  ASSERT_TRUE(second.ok()) << second.status().ToString();
  EXPECT_EQ(ReadText(fs::path(again.out) / "textons.yml"), ReadText(again.textons_file));
  EXPECT_EQ(second->at("textons").at("from_file"), again.textons_file);
  // A dictionary of another size than textons.k is refused.
  again.textons.k = 9;
  again.out = (root_ / "third").string();
  StatusOr<nlohmann::json> third = TrainBackgroundModels(again);
  ASSERT_FALSE(third.ok());
  EXPECT_NE(third.status().message().find("not --textons 9"), std::string::npos)
      << third.status().ToString();
}

}  // namespace
}  // namespace placerec
