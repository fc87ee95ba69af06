// placerec-train background (background_training.h) replaces a models directory only when the
// whole training has succeeded, and refuses training data it cannot learn from with an error.
// Runs on three real stanford_background images with a tiny configuration (8 textons, 5 trees).
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "common/training/background_training.h"
#include "common/util/paths.h"

namespace placerec {
namespace {

namespace fs = std::filesystem;

// Two training images with all five background classes, one test image.
const char* const kTrain[] = {"2000042", "3001336"};
const char* const kTest = "0000059";

std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

class BackgroundTrainingTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string source = DataDir("", PLACEREC_DEFAULT_DATA_DIR) + "/stanford_background";
    if (!fs::exists(source + "/images/" + std::string(kTest) + ".jpg")) {
      GTEST_SKIP() << "needs " << source << " (the shared evaluation data); set PLACEREC_DATA";
    }
    root_ = fs::path(::testing::TempDir()) / ("placerec_bgtrain_" + std::to_string(getpid()));
    fs::remove_all(root_);
    data_ = root_ / "data";
    for (const char* layer : {"images", "classes", "objects"}) {
      fs::create_directories(data_ / layer);
    }
    fs::copy_file(source + "/classes.txt", data_ / "classes.txt");
    auto copy = [&](const std::string& id) {
      fs::copy_file(source + "/images/" + id + ".jpg", data_ / "images" / (id + ".jpg"));
      for (const char* layer : {"classes", "objects"}) {
        fs::copy_file(source + "/" + layer + "/" + id + ".png", data_ / layer / (id + ".png"));
      }
    };
    std::ofstream train(data_ / "train.txt");
    for (const char* id : kTrain) {
      copy(id);
      train << id << "\n";
    }
    copy(kTest);
    std::ofstream(data_ / "test.txt") << kTest << "\n";

    config_.dataset = data_.string();
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

}  // namespace
}  // namespace placerec
