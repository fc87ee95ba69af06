// End-to-end: the whole pipeline on a real run from ../shared/data, scored as placerec-eval
// scores it. The floors are set honestly below what was measured (see the README's figures).
#include <gtest/gtest.h>

#include "common/eval/run.h"
#include "common/util/paths.h"
#include "tools/eval_runner.h"

namespace placerec {
namespace {

std::string DataRoot() { return DataDir("", PLACEREC_DEFAULT_DATA_DIR); }

StatusOr<placerec::Run> LoadOrSkip(const std::string& dataset, const std::string& name) {
  return LoadRun(DataRoot() + "/" + dataset, name);
}

// Recall at 100 % precision on corridor_loop, measured with each segmentation (README,
// "Figures"): Perceptual Organization (the default) 0.591, superpixels as objects 0.750. The
// floors leave room for noise and small changes; they are not the targets.
constexpr double kOrganizationRecallFloor = 0.5;
constexpr double kSuperpixelRecallFloor = 0.6;

void ExpectCorridorRecall(SegmentationMethod segmentation, double floor) {
  const std::string dataset = DataRoot() + "/rtabmap_indoor";
  if (!PathExists(dataset + "/runs/corridor_loop.frames.csv")) {
    GTEST_SKIP() << "needs " << dataset
                 << "/runs/corridor_loop.frames.csv (the shared evaluation data); set "
                    "PLACEREC_DATA to the folder that holds rtabmap_indoor/";
  }
  StatusOr<placerec::Run> run = LoadOrSkip("rtabmap_indoor", "corridor_loop");
  ASSERT_TRUE(run.ok()) << run.status().ToString();
  EvalOptions eval;
  eval.progress = false;
  eval.pictures = 0;
  RecognizerOptions options;
  options.analyzer.segmentation = segmentation;
  StatusOr<EvalReport> report = EvaluateRun(*run, options, eval);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  ASSERT_EQ(report->answers.size(), 84u);
  EXPECT_EQ(report->score.revisit_frames, 44);
  const double recall = report->score.recall_at_100_precision;
  ::testing::Test::RecordProperty("recall_at_100_precision", std::to_string(recall));
  ::testing::Test::RecordProperty("max_f1", std::to_string(report->score.max_f1));
  EXPECT_GE(recall, floor) << report->summary.dump(2);
}

TEST(EndToEndTest, CorridorLoopWithPerceptualOrganization) {
  ExpectCorridorRecall(SegmentationMethod::kOrganization, kOrganizationRecallFloor);
}

TEST(EndToEndTest, CorridorLoopWithSuperpixels) {
  ExpectCorridorRecall(SegmentationMethod::kSuperpixels, kSuperpixelRecallFloor);
}

}  // namespace
}  // namespace placerec
