// Tests of the frame analyzer (frame_analyzer.h): the segmenter it is given or makes, and the
// objects it finds on a synthetic street.
#include <limits>
#include <memory>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "common/pipeline/frame_analyzer.h"
#include "common/pipeline/pipeline_test_util.h"

namespace placerec {
namespace {

using pipeline_test::SyntheticAnalyzerOptions;
using pipeline_test::View;
using pipeline_test::World;

TEST(FrameAnalyzerTest, MissingModelsSayWhatToDo) {
  AnalyzerOptions options;
  options.organization.models_dir = ::testing::TempDir() + "/no_such_models_dir";
  const StatusOr<std::unique_ptr<Segmenter>> organization = MakeSegmenter(options);
  ASSERT_FALSE(organization.ok());
  EXPECT_NE(organization.status().message().find("placerec-train background"), std::string::npos)
      << organization.status().message();
  options.segmentation = SegmentationMethod::kSuperpixels;
  const StatusOr<std::unique_ptr<Segmenter>> superpixels = MakeSegmenter(options);
  ASSERT_TRUE(superpixels.ok()) << superpixels.status().message();
  EXPECT_EQ((*superpixels)->name(), "superpixels");
}

TEST(FrameAnalyzerTest, FindsObjectsOnTexturedBuildings) {
  const cv::Mat world = World(1);
  const FrameAnalyzer analyzer{SyntheticAnalyzerOptions()};
  const FrameObservation observation = analyzer.Analyze(View(world, 300));
  EXPECT_GT(observation.features.size(), 50);
  EXPECT_GE(observation.objects.size(), 3u);
  EXPECT_FALSE(observation.colourless);
  for (const SceneObject& object : observation.objects) {
    EXPECT_GE(object.sift_count(), 9);
    EXPECT_TRUE(object.colour.known());
  }
  // A grey copy of the frame carries no colour: no object gets a colour signature.
  cv::Mat grey;
  cv::cvtColor(View(world, 300), grey, cv::COLOR_BGR2GRAY);
  cv::cvtColor(grey, grey, cv::COLOR_GRAY2BGR);
  const FrameObservation grey_observation = analyzer.Analyze(grey);
  EXPECT_TRUE(grey_observation.colourless);
  for (const SceneObject& object : grey_observation.objects) EXPECT_FALSE(object.colour.known());
}

// A cheap camera's 160 px frame is processed at 640 px: several times the keypoints, and
// objects with enough of them to be matched, where the frame at its own size has few.
TEST(FrameAnalyzerTest, SmallFramesAreScaledUp) {
  const cv::Mat small = ResizeToWidth(View(World(1), 300), 160);
  AnalyzerOptions options = SyntheticAnalyzerOptions();
  options.small_frame_width = AnalyzerOptions().small_frame_width;
  const FrameObservation upscaled = FrameAnalyzer(options).Analyze(small);
  EXPECT_EQ(upscaled.original_size.width, 160);
  EXPECT_EQ(upscaled.processed_size.width, AnalyzerOptions().upscaled_width);
  EXPECT_DOUBLE_EQ(upscaled.scale, AnalyzerOptions().upscaled_width / 160.0);
  options.small_frame_width = 0;
  const FrameObservation kept = FrameAnalyzer(options).Analyze(small);
  EXPECT_EQ(kept.processed_size.width, 160);
  EXPECT_GT(upscaled.features.size(), 2 * kept.features.size());
  EXPECT_GT(upscaled.objects.size(), kept.objects.size());
}

// A phone's photo or an HD camera's frame is processed at most 960 px wide and 960^2 pixels by
// default (it was processed at full size, at many times the cost: docs/results.md); a portrait
// photo is bounded by the pixels; the boxes the server sends are scaled back by `scale`.
TEST(FrameAnalyzerTest, LargeFramesAreScaledDownByDefault) {
  const AnalyzerOptions defaults;
  ASSERT_EQ(defaults.max_image_width, 960);
  AnalyzerOptions options = SyntheticAnalyzerOptions();
  options.max_image_width = defaults.max_image_width;
  const cv::Mat world = World(1);
  const FrameObservation hd = FrameAnalyzer(options).Analyze(ResizeToWidth(View(world, 300), 1920));
  EXPECT_EQ(hd.original_size.width, 1920);
  EXPECT_EQ(hd.processed_size.width, 960);
  EXPECT_NEAR(hd.scale, 0.5, 1e-9);
  cv::Mat portrait;
  cv::resize(View(world, 300), portrait, cv::Size(1512, 2016));
  const FrameObservation tall = FrameAnalyzer(options).Analyze(portrait);
  EXPECT_LE(tall.processed_size.area(), 960 * 960);
  EXPECT_GT(tall.processed_size.area(), 950 * 950);
  EXPECT_LT(tall.processed_size.width, 960);
  EXPECT_NEAR(static_cast<double>(tall.processed_size.height) / tall.processed_size.width,
              2016.0 / 1512.0, 0.01);
  // 0 keeps the frame's size.
  options.max_image_width = 0;
  const FrameObservation kept =
      FrameAnalyzer(options).Analyze(ResizeToWidth(View(world, 300), 1280));
  EXPECT_EQ(kept.processed_size.width, 1280);
  EXPECT_EQ(ProcessedWidthCap(cv::Size(1280, 720), 0), 0);
  EXPECT_EQ(ProcessedWidthCap(cv::Size(1920, 1080), 960), 960);
  EXPECT_EQ(ProcessedWidthCap(cv::Size(960, 8000), 960), 332);
  // A cap beyond any frame keeps the frame's size (its square overflowed an int: frames went to
  // one pixel wide).
  EXPECT_EQ(ProcessedWidthCap(cv::Size(1310, 1191), std::numeric_limits<int>::max()),
            std::numeric_limits<int>::max());
}

// A tall, narrow frame within the decoder's limits (16 x 1024 px, a few hundred bytes as PNG) was
// scaled up to 640 x 40,960 (79 s and 6 GB for one frame); its pictures were as tall. The scale
// up now stops at 2 x 640^2 pixels, and the pictures at twice their width in height.
TEST(FrameAnalyzerTest, ATallNarrowFrameIsNotScaledIntoAHugeOne) {
  const AnalyzerOptions defaults;
  AnalyzerOptions options = SyntheticAnalyzerOptions();
  options.small_frame_width = defaults.small_frame_width;
  options.upscaled_width = defaults.upscaled_width;
  options.thumbnail_width = defaults.thumbnail_width;
  options.preview_width = defaults.preview_width;
  const cv::Mat tall(1024, 16, CV_8UC3, cv::Scalar(30, 60, 90));
  const FrameObservation observation = FrameAnalyzer(options).Analyze(tall);
  EXPECT_LE(static_cast<double>(observation.processed_size.area()),
            2.0 * defaults.upscaled_width * defaults.upscaled_width);
  EXPECT_GT(observation.processed_size.width, 16);  // still scaled up, within the budget
  EXPECT_LE(observation.thumbnail.rows, 2 * defaults.thumbnail_width);
  EXPECT_LE(observation.preview.rows, 2 * defaults.preview_width);
  EXPECT_GE(observation.thumbnail.cols, 1);
}

}  // namespace
}  // namespace placerec
