// End-to-end: scene segmentation on real labelled images from ../shared/data, scored with the
// object-level accuracy of `placerec-eval segment` (seed eq. 6.2): the learned merging against
// the seed's Perceptual Organization and the initial superpixels on the whole
// stanford_background test split; the margins are set below what was measured.
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/organization/scene_organizer.h"
#include "common/training/labelled_dataset.h"
#include "common/util/paths.h"
#include "tools/segment_command.h"

namespace placerec {
namespace {

struct Scores {
  ObjectScoreSummary learned;      // the default: learned merging
  ObjectScoreSummary seed;         // the seed's Perceptual Organization alone
  ObjectScoreSummary superpixels;  // the initial partition, ungrouped
};

TEST(SegmentationEndToEndTest, LearnedMergingGroupsBetterThanTheSeedRuleAndSuperpixels) {
  const std::string dataset = DataDir("", PLACEREC_DEFAULT_DATA_DIR) + "/stanford_background";
  if (!PathExists(dataset + "/test.txt")) {
    GTEST_SKIP() << "needs " << dataset << " (the shared evaluation data)";
  }
  const SceneOrganizerOptions learned_options = SceneOrganizerOptions::ForSegmentation();
  // The shipped models (models/) are part of the repository: failing to load them fails the test.
  StatusOr<SceneOrganizer> learned = SceneOrganizer::Create(learned_options);
  ASSERT_TRUE(learned.ok()) << learned.status().ToString();
  // The seed's rule on the same background decision.
  SceneOrganizerOptions seed_options = SceneOrganizerOptions::ForSegmentation();
  seed_options.learned_merge = false;
  seed_options.organization = OrganizationOptions();
  const SceneOrganizer seed(seed_options, std::make_shared<BackgroundModel>(learned->model()));

  StatusOr<std::vector<std::string>> ids = ReadSplit(dataset, "test");
  StatusOr<ClassTable> table = ReadClassTable(dataset);
  ASSERT_TRUE(ids.ok() && table.ok());
  ASSERT_EQ(ids->size(), 143u);
  Scores scores;
  for (size_t i = 0; i < ids->size(); ++i) {
    StatusOr<LabelledImage> image = ReadLabelledImage(dataset, (*ids)[i]);
    ASSERT_TRUE(image.ok()) << image.status().ToString();
    const WorkingImage working =
        MakeWorkingImage(image->bgr, learned_options.superpixels.working_width);
    const cv::Mat objects = LayerAtSize(image->objects, working.bgr.size());
    const cv::Mat classes = LayerAtSize(image->classes, working.bgr.size());
    auto score = [&](const SceneSegmentation& s, ObjectScoreSummary* summary) {
      // Every pixel in exactly one segment.
      double min_id = 0;
      double max_id = 0;
      cv::minMaxLoc(s.labels, &min_id, &max_id);
      EXPECT_EQ(min_id, 0);
      EXPECT_EQ(static_cast<int>(max_id) + 1, s.size());
      summary->Add(ScoreObjects(s.labels, objects, classes, *table, 0.005), *table);
    };
    score(learned->Segment(working), &scores.learned);
    score(seed.Segment(working), &scores.seed);
    score(learned->ClassifiedSuperpixels(working), &scores.superpixels);
  }
  const double learned_mean = scores.learned.Mean();
  const double seed_mean = scores.seed.Mean();
  const double superpixel_mean = scores.superpixels.Mean();
  ::testing::Test::RecordProperty("learned", std::to_string(learned_mean));
  ::testing::Test::RecordProperty("seed", std::to_string(seed_mean));
  ::testing::Test::RecordProperty("superpixels", std::to_string(superpixel_mean));
  // Mean object IoU in percent; the learned merging must beat the seed's Perceptual
  // Organization and the ungrouped initial superpixels by these margins (learned and seed PO as
  // measured: docs/results.md; the initial superpixels were last recorded in
  // docs/experiments/2026-11-29-learned-merging.md).
  std::printf("object IoU on %zu images: learned %.1f, seed PO %.1f, superpixels %.1f\n",
              ids->size(), learned_mean, seed_mean, superpixel_mean);
  EXPECT_GT(learned_mean, seed_mean + 2.5);
  EXPECT_GT(learned_mean, superpixel_mean + 5.0);
}

}  // namespace
}  // namespace placerec
