// placerec-train boundary (boundary_training.h) on three real stanford_background images with a
// tiny configuration: the model it writes scores the object boundaries of an unseen image above
// the edges inside objects, its manifest says what it was trained on, and data it cannot learn
// from is refused without writing anything.
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "common/organization/filter_bank.h"
#include "common/segmentation/superpixels.h"
#include "common/training/boundary_training.h"
#include "common/training/labelled_dataset.h"
#include "common/util/paths.h"

namespace placerec {
namespace {

namespace fs = std::filesystem;

const char* const kTrain[] = {"2000042", "3001336", "0000176"};
const char* const kTest = "0000059";

// Mean learned score of the superpixel-crack pixels of kTest on its ground-truth object
// boundaries and off them.
struct OnOff {
  double on = 0;
  double off = 0;
  int on_count = 0;
  int off_count = 0;
};

OnOff ScoreTestImage(const BoundaryModel& model, const std::string& dataset,
                     const SceneOrganizerOptions& organizer) {
  OnOff result;
  StatusOr<LabelledImage> image = ReadLabelledImage(dataset, kTest);
  if (!image.ok()) {
    ADD_FAILURE() << "cannot read " << kTest << ": " << image.status().ToString();
    return result;
  }
  const WorkingImage working = MakeWorkingImage(image->bgr, organizer.superpixels.working_width);
  const SceneSegmentation superpixels = ComputeSuperpixels(working, organizer.superpixels);
  const cv::Mat cracks = CrackPixels(superpixels.labels);
  const cv::Mat scores = model.ScoreMap(ComputeFilterBank(working.lab), cracks);
  const cv::Mat object_cracks = CrackPixels(LayerAtSize(image->objects, working.bgr.size()));
  for (int y = 0; y < cracks.rows; ++y) {
    for (int x = 0; x < cracks.cols; ++x) {
      if (!cracks.at<uint8_t>(y, x)) continue;
      if (object_cracks.at<uint8_t>(y, x)) {
        result.on += scores.at<float>(y, x);
        ++result.on_count;
      } else {
        result.off += scores.at<float>(y, x);
        ++result.off_count;
      }
    }
  }
  if (result.on_count > 0) result.on /= result.on_count;
  if (result.off_count > 0) result.off /= result.off_count;
  return result;
}

class BoundaryTrainingTest : public ::testing::Test {
 protected:
  void SetUp() override {
    source_ = DataDir("", PLACEREC_DEFAULT_DATA_DIR) + "/stanford_background";
    if (!fs::exists(source_ + "/images/" + std::string(kTest) + ".jpg")) {
      GTEST_SKIP() << "needs " << source_ << " (the shared evaluation data); set PLACEREC_DATA";
    }
    root_ = fs::path(::testing::TempDir()) / ("placerec_boundary_" + std::to_string(getpid()));
    fs::remove_all(root_);
    data_ = root_ / "data";
    for (const char* layer : {"images", "classes", "objects"})
      fs::create_directories(data_ / layer);
    std::ofstream train(data_ / "train.txt");
    for (const char* id : kTrain) {
      Copy(id);
      train << id << "\n";
    }
    Copy(kTest);
    std::ofstream(data_ / "test.txt") << kTest << "\n";
    config_.dataset = data_.string();
    config_.out = (root_ / "models").string();
    config_.samples_per_image = 200;
    config_.boost.weak_count = 20;
    config_.progress = false;
  }
  void TearDown() override {
    if (!root_.empty() && !HasFailure()) fs::remove_all(root_);
  }
  void Copy(const std::string& id) {
    fs::copy_file(source_ + "/images/" + id + ".jpg", data_ / "images" / (id + ".jpg"));
    for (const char* layer : {"classes", "objects"}) {
      fs::copy_file(source_ + "/" + layer + "/" + id + ".png", data_ / layer / (id + ".png"));
    }
  }

  std::string source_;
  fs::path root_;
  fs::path data_;
  BoundaryTrainingConfig config_;
};

TEST_F(BoundaryTrainingTest, LearnedModelScoresObjectBoundariesOfAnUnseenImageHigher) {
  const StatusOr<nlohmann::json> manifest = TrainBoundaryModel(config_);
  ASSERT_TRUE(manifest.ok()) << manifest.status().ToString();
  EXPECT_EQ((*manifest)["data"]["images"], 3);
  EXPECT_EQ((*manifest)["accuracy"]["training"]["pixels"], 3 * 2 * 200);
  EXPECT_TRUE(fs::exists(fs::path(config_.out) / "boundary.json"));
  const StatusOr<BoundaryModel> model = BoundaryModel::Load(config_.out);
  ASSERT_TRUE(model.ok()) << model.status().ToString();

  const OnOff scores = ScoreTestImage(*model, config_.dataset, config_.organizer);
  ASSERT_GT(scores.on_count, 100);
  ASSERT_GT(scores.off_count, 100);
  EXPECT_GT(scores.on, scores.off + 0.2);
  const nlohmann::json& test = (*manifest)["accuracy"]["test"];
  EXPECT_GT(test["balanced_accuracy"].get<double>(), 52.0);  // chance: 50
}

TEST_F(BoundaryTrainingTest, LeftOutFoldAndHoldoutAreRecorded) {
  config_.leave_out_fold = Fold{1, 2};
  config_.holdout = 1;
  config_.eval_split = "";
  const StatusOr<nlohmann::json> manifest = TrainBoundaryModel(config_);
  ASSERT_TRUE(manifest.ok()) << manifest.status().ToString();
  // One held out, and of the other two the second half (one image) left out.
  EXPECT_EQ((*manifest)["data"]["images"], 1);
  EXPECT_EQ((*manifest)["data"]["left_out_fold"], "1/2");
  EXPECT_EQ((*manifest)["accuracy"]["held_out"]["images"], 1);
  EXPECT_FALSE((*manifest)["accuracy"].contains("test"));
}

TEST_F(BoundaryTrainingTest, ImageWithoutObjectsIsRefusedAndNothingIsWritten) {
  fs::remove(data_ / "objects" / (std::string(kTrain[1]) + ".png"));
  const StatusOr<nlohmann::json> manifest = TrainBoundaryModel(config_);
  ASSERT_FALSE(manifest.ok());
  EXPECT_NE(manifest.status().message().find(kTrain[1]), std::string::npos);
  EXPECT_FALSE(fs::exists(fs::path(config_.out) / BoundaryModel::kFileName));
  EXPECT_FALSE(fs::exists(fs::path(config_.out) / "boundary.json"));
}

// The shipped boundary model (models/, part of the repository) on a test image it was not
// trained on: object boundaries score clearly above the edges inside objects.
TEST_F(BoundaryTrainingTest, ShippedModelSeparatesObjectBoundariesOfATestImage) {
  const StatusOr<BoundaryModel> model = BoundaryModel::Load(PLACEREC_MODELS_DIR);
  ASSERT_TRUE(model.ok()) << "the shipped boundary model in " << PLACEREC_MODELS_DIR
                          << " does not load: " << model.status().ToString();
  const OnOff scores = ScoreTestImage(*model, source_, SceneOrganizerOptions::ForSegmentation());
  ASSERT_GT(scores.on_count, 100);
  ASSERT_GT(scores.off_count, 100);
  EXPECT_GT(scores.on, 0.0);
  EXPECT_LT(scores.off, 0.0);
}

}  // namespace
}  // namespace placerec
