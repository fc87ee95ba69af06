// Tests of the recognizer (recognizer.h; seed §5.7) on frames of a synthetic street: request
// checks, a second robot recognising the places the first mapped, a map reopened from its file,
// and a robot standing still.
#include <unistd.h>

#include <cstdio>
#include <memory>
#include <random>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "common/pipeline/pipeline_test_util.h"
#include "common/pipeline/place_map.h"
#include "common/pipeline/recognizer.h"
#include "common/storage/sqlite_store.h"

namespace placerec {
namespace {

using pipeline_test::kStep;
using pipeline_test::kViewWidth;
using pipeline_test::SyntheticAnalyzerOptions;
using pipeline_test::View;
using pipeline_test::World;

RecognizerOptions TestOptions() {
  RecognizerOptions options;
  options.analyzer = SyntheticAnalyzerOptions();
  return options;
}

std::unique_ptr<PlaceMap> OpenMap(const std::string& path, const RecognizerOptions& options) {
  StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(path, SqliteStoreOptions());
  EXPECT_TRUE(store.ok()) << store.status().ToString();
  StatusOr<std::unique_ptr<PlaceMap>> map = PlaceMap::Open(std::move(*store), options.index);
  EXPECT_TRUE(map.ok()) << map.status().ToString();
  return std::move(*map);
}

TEST(RecognizerOptionsTest, DefaultsPass) {
  std::string error;
  EXPECT_TRUE(RecognizerOptions().Check(&error)) << error;
  RecognizerOptions bad;
  bad.analyzer.max_image_width = 10;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_NE(error.find("max_image_width"), std::string::npos);
}

TEST(RecognizerTest, RejectsBadRequestsWithoutChangingAnything) {
  const RecognizerOptions options = TestOptions();
  std::unique_ptr<PlaceMap> map = OpenMap(":memory:", options);
  Recognizer recognizer(options, map.get());
  const cv::Mat frame = View(World(2), 0);
  EXPECT_EQ(recognizer.Process({"", 0, 0, true}, frame).status.code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(recognizer.Process({std::string(65, 'r'), 0, 0, true}, frame).status.code(),
            StatusCode::kInvalidArgument);
  ASSERT_TRUE(recognizer.Process({"a", 5, 0, true}, frame).status.ok());
  const RecognitionResult stale = recognizer.Process({"a", 5, 0, true}, frame);
  EXPECT_EQ(stale.status.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(stale.status.message().find("not after 5"), std::string::npos);
  // Query-only frames need no order.
  EXPECT_TRUE(recognizer.Process({"a", 1, 0, false}, frame).status.ok());
}

// Removes a SQLite map file and its WAL companions.
void RemoveMapFiles(const std::string& path) {
  for (const char* suffix : {"", "-wal", "-shm"}) std::remove((path + suffix).c_str());
}

// Robot "a" drives along the street; robot "b" drives it again 13 pixels to the side. Every frame
// of "b" should be recognised as the frame of "a" taken at the nearest position.
TEST(RecognizerTest, SecondRobotRecognisesThePlacesTheFirstMapped) {
  const cv::Mat world = World(3);
  const RecognizerOptions options = TestOptions();
  // A file of this process's own: other runs of the suite on the machine share the temp folder.
  const std::string path =
      ::testing::TempDir() + "/placerec_recognizer_test_" + std::to_string(getpid()) + ".db";
  RemoveMapFiles(path);
  std::unique_ptr<PlaceMap> map = OpenMap(path, options);
  Recognizer recognizer(options, map.get());
  const int step = kStep;
  const int frames = (world.cols - kViewWidth) / step + 1;
  int64_t sequence = 0;
  int landmarks = 0;
  int duplicates = 0;
  for (int i = 0; i < frames; ++i) {
    const RecognitionResult result =
        recognizer.Process({"a", sequence++, i * 1000000LL, true}, View(world, i * step));
    ASSERT_TRUE(result.status.ok()) << result.status.ToString();
    if (i > 0) {
      EXPECT_GT(result.landmarks, 0) << "frame " << i;
    }
    // A frame whose strongest features all lie in the part it shares with the last one shows
    // nothing new and is not stored.
    if (result.duplicate) {
      ++duplicates;
      EXPECT_FALSE(result.place.IsValid());
      EXPECT_EQ(result.stored_descriptors, 0);
    } else {
      landmarks += result.landmarks;
    }
  }
  EXPECT_LE(duplicates, frames / 10);
  const MapCounts mapped = map->Counts();
  EXPECT_EQ(mapped.landmarks, landmarks);
  EXPECT_EQ(mapped.places, frames - 1 - duplicates);  // the first frame has no landmarks yet

  // Query-only frames leave the map exactly as it was.
  const StatusOr<uint64_t> before = map->Checksum();
  ASSERT_TRUE(before.ok());
  const RecognitionResult query = recognizer.Process({"handheld", 0, 0, false}, View(world, 1213));
  ASSERT_TRUE(query.status.ok());
  ASSERT_FALSE(query.matches.empty());
  EXPECT_NEAR(query.matches.front().place.sequence, 1213 / step, 1);
  EXPECT_EQ(query.landmarks, 0);
  EXPECT_EQ(*map->Checksum(), *before);
  EXPECT_EQ(map->Counts().landmarks, mapped.landmarks);

  int correct = 0;
  for (int i = 0; i < frames; ++i) {
    const RecognitionResult result = recognizer.Process(
        {"b", 1000 + i, 0, true}, View(world, std::min(i * step + 13, world.cols - kViewWidth)));
    ASSERT_TRUE(result.status.ok());
    if (result.matches.empty()) continue;
    const PlaceMatch& best = result.matches.front();
    if (best.place.robot == "a" && std::abs(best.place.sequence - i) <= 1) ++correct;
  }
  EXPECT_GE(correct, frames * 8 / 10) << correct << " of " << frames;

  // Reopening the file gives the same map and the same answers.
  const RecognitionResult before_close =
      recognizer.Process({"handheld", 0, 0, false}, View(world, 1213));
  ASSERT_FALSE(before_close.matches.empty());
  const MapCounts counts = map->Counts();
  map.reset();
  std::unique_ptr<PlaceMap> reopened = OpenMap(path, options);
  EXPECT_EQ(reopened->Counts().landmarks, counts.landmarks);
  EXPECT_EQ(reopened->Counts().descriptors, counts.descriptors);
  Recognizer again(options, reopened.get());
  const RecognitionResult after = again.Process({"handheld", 0, 0, false}, View(world, 1213));
  ASSERT_FALSE(after.matches.empty());
  EXPECT_EQ(after.matches.front().place.id, before_close.matches.front().place.id);
  EXPECT_EQ(after.matches.front().score, before_close.matches.front().score);
  reopened.reset();
  RemoveMapFiles(path);
}

// A robot that stands still for 30 s at 10 frames per second sends the same view 300 times: no
// frame is a loop closure to its own past, and the map keeps one place for the view. Once it
// has driven away and comes back after more than min_gap_seconds, its first place answers.
TEST(RecognizerTest, StandingStillIsNeverALoopClosureComingBackIs) {
  const cv::Mat world = World(5);
  const RecognizerOptions options = TestOptions();
  std::unique_ptr<PlaceMap> map = OpenMap(":memory:", options);
  Recognizer recognizer(options, map.get());
  int64_t sequence = 0;
  int64_t utime = 0;
  const FrameObservation start = recognizer.Analyze(View(world, 0));
  const FrameObservation next = recognizer.Analyze(View(world, kStep));
  // Two frames so that the start view has landmarks, then 300 copies of it.
  ASSERT_TRUE(recognizer.Recognize({"a", sequence++, utime, true}, next).status.ok());
  for (int f = 0; f < 300; ++f) {
    utime += 100000;
    const RecognitionResult result = recognizer.Recognize({"a", sequence++, utime, true}, start);
    ASSERT_TRUE(result.status.ok());
    EXPECT_FALSE(result.loop_closure) << "copy " << f;
    for (const PlaceMatch& match : result.matches) EXPECT_NE(match.place.robot, "a");
  }
  EXPECT_EQ(map->Counts().places, 1);
  // Drive along the street, one view a second, then turn back to the start.
  for (int x = kStep; x + kViewWidth <= world.cols; x += kStep) {
    utime += 1000000;
    ASSERT_TRUE(recognizer.Process({"a", sequence++, utime, true}, View(world, x)).status.ok());
  }
  utime += 1000000;
  const RecognitionResult back = recognizer.Process({"a", sequence++, utime, true}, View(world, 0));
  ASSERT_TRUE(back.status.ok());
  ASSERT_FALSE(back.matches.empty());
  EXPECT_TRUE(back.loop_closure);
  EXPECT_EQ(back.matches.front().place.robot, "a");
  EXPECT_LE(back.matches.front().place.sequence, 302);  // the start, or the view 80 px on
}

}  // namespace
}  // namespace placerec
