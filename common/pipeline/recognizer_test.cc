// Tests of the recognizer (recognizer.h; seed §5.7): request checks, landmark selection and
// storage, lookups by other robots and by the robot itself, query-only frames; on frames of a
// synthetic street, and on synthetic observations (objects of random descriptors, no images)
// where exact counts are wanted.
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/organization/filter_bank.h"
#include "common/pipeline/flags.h"
#include "common/pipeline/pipeline_test_util.h"
#include "common/pipeline/place_map.h"
#include "common/pipeline/recognizer.h"
#include "common/recognition/recognition_test_util.h"
#include "common/storage/forwarding_store_testing.h"
#include "common/storage/sqlite_store.h"

namespace placerec {
namespace {

using pipeline_test::kStep;
using pipeline_test::kViewWidth;
using pipeline_test::SyntheticAnalyzerOptions;
using pipeline_test::View;
using pipeline_test::World;
using recognition_test::Noisy;
using recognition_test::RandomDescriptors;

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

TEST(RecognizerOptionsTest, ChangeFlagsReachTheDetectorAndBadValuesAreNamed) {
  RecognizerOptions options;
  FlagParser parser("test");
  AddRecognizerFlags(&parser, &options);
  const char* argv[] = {"prog", "--change-min-points",     "8", "--change-min-inlier-share",
                        "0.1",  "--change-max-references", "2", "--change-reference-window",
                        "5"};
  bool help = false;
  ASSERT_TRUE(parser.Parse(9, argv, 1, &help).ok());
  EXPECT_EQ(options.change.min_points, 8);
  EXPECT_DOUBLE_EQ(options.change.min_inlier_share, 0.1);
  EXPECT_EQ(options.change.max_references, 2);
  EXPECT_DOUBLE_EQ(options.change.reference_window_seconds, 5.0);
  std::string error;
  EXPECT_TRUE(options.Check(&error)) << error;
  const char* too_few[] = {"prog", "--change-min-points", "3"};
  ASSERT_TRUE(parser.Parse(3, too_few, 1, &help).ok());
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("min_points"), std::string::npos) << error;
  const char* sure[] = {"prog", "--change-min-points", "12", "--change-min-class-confidence",
                        "1.5"};
  ASSERT_TRUE(parser.Parse(5, sure, 1, &help).ok());
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("min class confidence"), std::string::npos) << error;
}

TEST(RecognizerOptionsTest, ExactPlaceFlagsReachTheIndexAndTheSeedModeTurnsThemOff) {
  RecognizerOptions options;
  FlagParser parser("test");
  AddRecognizerFlags(&parser, &options);
  const char* argv[] = {"prog", "--exact-places", "2", "--exact-max-comparisons", "5000"};
  bool help = false;
  ASSERT_TRUE(parser.Parse(5, argv, 1, &help).ok());
  EXPECT_EQ(options.index.exact_places, 2);
  EXPECT_EQ(options.index.exact_max_comparisons, 5000);
  std::string error;
  EXPECT_TRUE(options.Check(&error)) << error;
  // The seed's recognition (§5.6) judges places by their object matches alone.
  options.mode = RecognitionMode::kSeed;
  EXPECT_EQ(EffectiveOptions(options).index.exact_places, 0);
  EXPECT_EQ(EffectiveOptions(options).index.vote_places, 0);
  const char* negative[] = {"prog", "--exact-places", "-1"};
  ASSERT_TRUE(parser.Parse(3, negative, 1, &help).ok());
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("exact_places"), std::string::npos) << error;
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
TEST(RecognizerTest, PlacesKeepThumbnailsAndARevisitIsComparedWithThem) {
  const cv::Mat world = World(5);
  const RecognizerOptions options = TestOptions();
  std::unique_ptr<PlaceMap> map = OpenMap(":memory:", options);
  Recognizer recognizer(options, map.get());
  PlaceId stored;
  for (int i = 0; i < 4; ++i) {
    const RecognitionResult result =
        recognizer.Process({"a", i, i * 1000000LL, true}, View(world, i * kStep));
    ASSERT_TRUE(result.status.ok()) << result.status.ToString();
    if (result.place.IsValid()) stored = result.place;
  }
  ASSERT_TRUE(stored.IsValid());
  StatusOr<std::vector<uint8_t>> jpeg = map->LoadThumbnail(stored);
  ASSERT_TRUE(jpeg.ok());
  const cv::Mat thumbnail = cv::imdecode(*jpeg, cv::IMREAD_COLOR);
  EXPECT_EQ(thumbnail.cols, options.analyzer.thumbnail_width);

  // Another robot at the last place, much later: a loop closure compared with the stored view.
  const RecognitionResult revisit =
      recognizer.Process({"b", 0, 3600 * 1000000LL, false}, View(world, 3 * kStep));
  ASSERT_TRUE(revisit.status.ok());
  if (!revisit.loop_closure) GTEST_SKIP() << "the synthetic revisit is no loop closure";
  EXPECT_TRUE(revisit.change.checked) << revisit.change.why_not;
  EXPECT_TRUE(revisit.change.place.id.IsValid());

  // Without thumbnails nothing is compared, and the report says why.
  RecognizerOptions bare = options;
  bare.analyzer.thumbnail_width = 0;
  std::unique_ptr<PlaceMap> bare_map = OpenMap(":memory:", bare);
  Recognizer bare_recognizer(bare, bare_map.get());
  for (int i = 0; i < 4; ++i) {
    bare_recognizer.Process({"a", i, i * 1000000LL, true}, View(world, i * kStep));
  }
  const RecognitionResult blind =
      bare_recognizer.Process({"b", 0, 3600 * 1000000LL, false}, View(world, 3 * kStep));
  if (blind.loop_closure) {
    EXPECT_FALSE(blind.change.checked);
    EXPECT_FALSE(blind.change.why_not.empty());
  }
}

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
// has driven away and comes back after more than min_gap_seconds, its first places answer.
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
  // Back at the start, it drives the street again: a revisit is a run of frames matching the
  // route in step (sequence_support.h), so within a few frames its first places answer.
  // Where each stored place was taken along the street (pixels): sequence 0 at kStep, 1 (the
  // view it stood still at) at 0, the drive from 301 on.
  auto position = [](int64_t s) { return s == 0 ? kStep : s == 1 ? 0 : (s - 300) * kStep; };
  bool closed = false;
  for (int k = 0; k < 4 && !closed; ++k) {
    utime += 1000000;
    const RecognitionResult back =
        recognizer.Process({"a", sequence++, utime, true}, View(world, k * kStep));
    ASSERT_TRUE(back.status.ok());
    if (!back.loop_closure) continue;
    closed = true;
    EXPECT_EQ(back.matches.front().place.robot, "a");
    EXPECT_LE(std::abs(position(back.matches.front().place.sequence) - k * kStep), kStep)
        << "frame " << k << " back answered place " << back.matches.front().place.sequence;
  }
  EXPECT_TRUE(closed);
}

// ---- Synthetic observations ----

// A frame as the analyzer would observe it, built from its objects' descriptors (CV_8U x 128,
// one matrix per object, in this order): every keypoint belongs to its object, keypoints are
// strongest first in object order (response 1 / (1 + index)) and all turned 30 degrees.
FrameObservation Observation(const std::vector<cv::Mat>& objects) {
  FrameObservation observation;
  observation.original_size = cv::Size(640, 480);
  observation.processed_size = observation.original_size;
  std::mt19937 rng(static_cast<unsigned>(objects.size()));
  std::uniform_real_distribution<float> coordinate(0.0f, 1.0f);
  for (size_t o = 0; o < objects.size(); ++o) {
    SceneObject object;
    object.segment = static_cast<int>(o);
    object.box = cv::Rect(static_cast<int>(o) * 100, 100, 100, 200);
    object.working_box = object.box;
    object.descriptors = objects[o];
    for (int r = 0; r < objects[o].rows; ++r) {
      const int k = observation.features.size();
      const cv::Point2f pt(object.box.x + 100.0f * coordinate(rng),
                           object.box.y + 200.0f * coordinate(rng));
      observation.features.keypoints.emplace_back(pt, 4.0f, 30.0f, 1.0f / (1.0f + k));
      observation.features.descriptors.push_back(objects[o].row(r));
      object.keypoints.push_back(k);
    }
    observation.objects.push_back(std::move(object));
  }
  return observation;
}

// The rows of `parts`, one matrix under the other.
cv::Mat Rows(const std::vector<cv::Mat>& parts) {
  cv::Mat out;
  cv::vconcat(parts, out);
  return out;
}

// Two frames of robot "a": frame 0 shows objects A and B; frame 1 shows C and A again, 12 of A's
// 20 features seen anew (its other 8 are new), so A is frame 1's one landmark. The objects'
// descriptors and the generator stay at hand for other views of them.
struct TwoFrames {
  explicit TwoFrames(unsigned seed) : rng(seed) {
    a = RandomDescriptors(20, &rng);
    b = RandomDescriptors(20, &rng);
    c = RandomDescriptors(20, &rng);
    a_again = Rows({Noisy(a.rowRange(0, 12), &rng), RandomDescriptors(8, &rng)});
  }
  FrameObservation First() const { return Observation({a, b}); }
  FrameObservation Second() const { return Observation({c, a_again}); }

  std::mt19937 rng;
  cv::Mat a, b, c, a_again;
};

// Landmark selection (seed §5.7 step 4) decides what a frame stores: nothing for a robot's first
// frame; then its landmarks, by default only their features tracked from the previous frames,
// topped up with the landmarks' strongest other features to min_descriptors_per_place.
TEST(RecognizerTest, StoresOnlyLandmarksWithTheirTrackedFeaturesToppedUp) {
  struct Case {
    int min_descriptors_per_place;
    bool tracked_only;
    int stored;  // descriptors frame 1 stores
  };
  for (const Case& c :
       {Case{0, true, 12}, Case{15, true, 15}, Case{100, true, 20}, Case{0, false, 20}}) {
    SCOPED_TRACE("min_descriptors_per_place " + std::to_string(c.min_descriptors_per_place) +
                 (c.tracked_only ? ", tracked only" : ", every row"));
    const TwoFrames frames(41);
    RecognizerOptions options = TestOptions();
    options.min_descriptors_per_place = c.min_descriptors_per_place;
    options.store_tracked_descriptors_only = c.tracked_only;
    std::unique_ptr<PlaceMap> map = OpenMap(":memory:", options);
    Recognizer recognizer(options, map.get());

    const RecognitionResult first = recognizer.Recognize({"a", 0, 0, true}, frames.First());
    ASSERT_TRUE(first.status.ok()) << first.status.ToString();
    EXPECT_EQ(first.objects, 2);
    EXPECT_EQ(first.keypoints, 40);
    EXPECT_EQ(first.landmarks, 0);
    EXPECT_EQ(first.stored_descriptors, 0);
    EXPECT_FALSE(first.place.IsValid());  // no landmarks, no place
    EXPECT_EQ(first.map.places, 0);

    const RecognitionResult second = recognizer.Recognize({"a", 1, 1000000, true}, frames.Second());
    ASSERT_TRUE(second.status.ok()) << second.status.ToString();
    EXPECT_FALSE(second.duplicate);
    EXPECT_EQ(second.landmarks, 1);
    EXPECT_EQ(second.stored_descriptors, c.stored);
    EXPECT_TRUE(second.place.IsValid());
    EXPECT_EQ(second.map.places, 1);
    EXPECT_EQ(second.map.landmarks, 1);
    EXPECT_EQ(second.map.descriptors, c.stored);
    EXPECT_EQ(map->Counts().descriptors, c.stored);
  }
}

// Observations with what classification reads: a filter bank of a textured image and an object
// mask filling each object's box.
FrameObservation WithPixels(FrameObservation observation) {
  cv::Mat bgr(observation.processed_size, CV_8UC3);
  cv::randu(bgr, cv::Scalar::all(0), cv::Scalar::all(255));
  cv::Mat lab;
  bgr.convertTo(lab, CV_32F, 1.0 / 255.0);
  cv::cvtColor(lab, lab, cv::COLOR_BGR2Lab);
  observation.filter_bank = ComputeFilterBank(lab);
  for (SceneObject& object : observation.objects) {
    object.mask = cv::Mat(object.working_box.size(), CV_8U, cv::Scalar(255));
  }
  return observation;
}

// Stored landmarks keep the class the object classifiers give them (seed Ch. 4), and the map
// keeps it; with drop_movable, a landmark of a movable class is left out (seed §7.2.3): here every
// class counts as movable, so the landmark is surely left out.
TEST(RecognizerTest, LandmarksKeepTheirClassAndMovableOnesCanBeLeftOut) {
  const TwoFrames frames(41);
  for (const bool drop : {false, true}) {
    SCOPED_TRACE(drop ? "drop movable" : "keep every landmark");
    RecognizerOptions options = TestOptions();
    ASSERT_TRUE(options.classes.enabled);  // the default
    StatusOr<std::unique_ptr<ObjectClassLabeler>> labeler =
        ObjectClassLabeler::Load(options.classes);
    ASSERT_TRUE(labeler.ok()) << labeler.status().ToString();
    if (drop) {
      options.classes.drop_movable = true;
      options.classes.min_movable_confidence = 0.0;
      options.classes.movable_classes = (*labeler)->classifier().names();
    }
    std::unique_ptr<PlaceMap> map = OpenMap(":memory:", options);
    Recognizer recognizer(options, map.get());
    ASSERT_TRUE(recognizer.Recognize({"a", 0, 0, true}, WithPixels(frames.First())).status.ok());
    const RecognitionResult second =
        recognizer.Recognize({"a", 1, 1000000, true}, WithPixels(frames.Second()));
    ASSERT_TRUE(second.status.ok()) << second.status.ToString();
    if (drop) {
      EXPECT_EQ(second.movable_landmarks, 1);
      EXPECT_EQ(second.landmarks, 0);
      EXPECT_TRUE(second.stored_classes.empty());
      EXPECT_EQ(map->Counts().landmarks, 0);
      continue;
    }
    EXPECT_EQ(second.movable_landmarks, 0);
    EXPECT_EQ(second.landmarks, 1);
    ASSERT_EQ(second.stored_classes.size(), 1u);
    const std::vector<std::string>& names = (*labeler)->classifier().names();
    EXPECT_NE(std::find(names.begin(), names.end(), second.stored_classes[0]), names.end())
        << second.stored_classes[0];
    // A query of the same view names the matched landmark's class.
    const RecognitionResult query =
        recognizer.Recognize({"b", 0, 50000000, false}, WithPixels(frames.Second()));
    ASSERT_TRUE(query.status.ok());
    ASSERT_FALSE(query.matches.empty());
    ASSERT_EQ(query.matches[0].landmark_classes.size(), 1u);
    EXPECT_EQ(query.matches[0].landmark_classes[0].first, second.stored_classes[0]);
    EXPECT_EQ(query.matches[0].landmark_classes[0].second, 1);
  }
}

// The seed's recognition (§5.7 steps 5-6): a landmark that matches a stored object is not stored
// again, the place joins the object's scene set, and the seed's step 6 decides the loop.
TEST(RecognizerTest, SeedModeKeepsOneObjectPerLandmarkWithItsScenes) {
  const TwoFrames frames(41);
  RecognizerOptions options = TestOptions();
  options.mode = RecognitionMode::kSeed;
  std::unique_ptr<PlaceMap> map = OpenMap(":memory:", options);
  Recognizer recognizer(options, map.get());
  EXPECT_EQ(recognizer.options().query_objects, QueryObjects::kLandmarks);
  EXPECT_FALSE(recognizer.options().loop.geometric_verification);

  ASSERT_TRUE(recognizer.Recognize({"a", 0, 0, true}, frames.First()).status.ok());
  const RecognitionResult a = recognizer.Recognize({"a", 1, 1000000, true}, frames.Second());
  ASSERT_TRUE(a.status.ok());
  EXPECT_EQ(a.landmarks, 1);
  EXPECT_EQ(a.stored_descriptors, 20);  // the seed stores the object's descriptors
  EXPECT_FALSE(a.loop_closure);

  ASSERT_TRUE(recognizer.Recognize({"b", 0, 100000000, true}, frames.First()).status.ok());
  const RecognitionResult b = recognizer.Recognize({"b", 1, 101000000, true}, frames.Second());
  ASSERT_TRUE(b.status.ok()) << b.status.ToString();
  EXPECT_TRUE(b.loop_closure);  // its one landmark matched the one of a's place: 100 %
  ASSERT_FALSE(b.matches.empty());
  EXPECT_EQ(b.matches[0].place.id, a.place);
  EXPECT_EQ(b.matches[0].matched_landmarks, 1);
  EXPECT_EQ(b.stored_descriptors, 0);  // seen again, not stored again
  EXPECT_EQ(map->Counts().landmarks, 1);
  EXPECT_EQ(map->Counts().places, 2);
}

// Without object classes, landmarks are stored unclassified.
TEST(RecognizerTest, ObjectClassesOffStoresUnclassifiedLandmarks) {
  const TwoFrames frames(41);
  RecognizerOptions options = TestOptions();
  options.classes.enabled = false;
  std::unique_ptr<PlaceMap> map = OpenMap(":memory:", options);
  Recognizer recognizer(options, map.get());
  ASSERT_TRUE(recognizer.Recognize({"a", 0, 0, true}, WithPixels(frames.First())).status.ok());
  const RecognitionResult second =
      recognizer.Recognize({"a", 1, 1000000, true}, WithPixels(frames.Second()));
  ASSERT_TRUE(second.status.ok());
  EXPECT_EQ(second.stored_classes, std::vector<std::string>{""});
}

// A query-only frame is answered but changes neither the map nor the robot: the inserted frame
// after it is answered and stored exactly as without it, and its sequence number stays free.
TEST(RecognizerTest, QueryOnlyFramesChangeNeitherTheMapNorTheRobot) {
  TwoFrames frames(42);
  RecognizerOptions options = TestOptions();
  options.min_descriptors_per_place = 0;
  std::unique_ptr<PlaceMap> map = OpenMap(":memory:", options);
  Recognizer recognizer(options, map.get());
  ASSERT_TRUE(recognizer.Recognize({"a", 0, 0, true}, frames.First()).status.ok());
  const StatusOr<uint64_t> before = map->Checksum();
  ASSERT_TRUE(before.ok());
  // The query shows C, which frame 1 shows too, and has the sequence number frame 1 will take.
  const RecognitionResult query = recognizer.Recognize(
      {"a", 1, 500000, false},
      Observation({Noisy(frames.c, &frames.rng), RandomDescriptors(20, &frames.rng)}));
  ASSERT_TRUE(query.status.ok()) << query.status.ToString();
  EXPECT_EQ(query.landmarks, 0);
  EXPECT_EQ(query.stored_descriptors, 0);
  EXPECT_FALSE(query.place.IsValid());
  EXPECT_EQ(*map->Checksum(), *before);
  // Stages of a query: no insert.
  std::vector<std::string> stages;
  for (const auto& [stage, ms] : query.timings) stages.push_back(stage);
  EXPECT_EQ(stages, (std::vector<std::string>{"landmarks", "recent_past", "index", "decision"}));

  // Had the query been remembered among the robot's previous frames, C would be a landmark too.
  const RecognitionResult second = recognizer.Recognize({"a", 1, 1000000, true}, frames.Second());
  ASSERT_TRUE(second.status.ok()) << second.status.ToString();
  EXPECT_EQ(second.landmarks, 1);
  EXPECT_EQ(second.stored_descriptors, 12);
  stages.clear();
  for (const auto& [stage, ms] : second.timings) stages.push_back(stage);
  EXPECT_EQ(stages, (std::vector<std::string>{"landmarks", "recent_past", "index", "decision",
                                              "classes", "insert"}));
}

// A store whose next AddPlace fails, as a full disk makes it.
class FailingStore : public testing_storage::ForwardingStore {
 public:
  using ForwardingStore::ForwardingStore;

  Status AddPlace(Place* place, std::vector<Landmark>* landmarks) override {
    if (fail_next_) {
      fail_next_ = false;
      return Status::IoError("database or disk is full");
    }
    return ForwardingStore::AddPlace(place, landmarks);
  }

  void FailNext() { fail_next_ = true; }

 private:
  bool fail_next_ = false;
};

// A robot that stands still while the disk is full: the frame that failed to be stored must not
// become its last distinct frame, or every later frame of the view counted as a copy of it and
// the view was never stored once the disk had room again.
TEST(RecognizerTest, AFrameThatWasNotStoredLeavesTheRecentPastAsItWas) {
  const TwoFrames frames(43);
  RecognizerOptions options = TestOptions();
  options.min_descriptors_per_place = 0;
  StatusOr<std::unique_ptr<LandmarkStore>> inner = OpenSqliteStore(":memory:", {});
  ASSERT_TRUE(inner.ok());
  auto failing = std::make_unique<FailingStore>(std::move(*inner));
  FailingStore* store = failing.get();
  StatusOr<std::unique_ptr<PlaceMap>> map = PlaceMap::Open(std::move(failing), options.index);
  ASSERT_TRUE(map.ok()) << map.status().ToString();
  Recognizer recognizer(options, map->get());
  ASSERT_TRUE(recognizer.Recognize({"a", 0, 0, true}, frames.First()).status.ok());

  store->FailNext();
  const RecognitionResult failed = recognizer.Recognize({"a", 1, 1000000, true}, frames.Second());
  EXPECT_EQ(failed.status.code(), StatusCode::kIoError);
  EXPECT_FALSE(failed.place.IsValid());
  EXPECT_EQ((*map)->Counts().places, 0);

  // The next frame of the same view, the disk has room again: stored.
  const RecognitionResult again = recognizer.Recognize({"a", 2, 1100000, true}, frames.Second());
  ASSERT_TRUE(again.status.ok()) << again.status.ToString();
  EXPECT_FALSE(again.duplicate);
  EXPECT_TRUE(again.place.IsValid());
  EXPECT_EQ((*map)->Counts().places, 1);
  // Stored, it is the robot's last distinct frame: one more copy of the view is a duplicate.
  const RecognitionResult copy = recognizer.Recognize({"a", 3, 1200000, true}, frames.Second());
  ASSERT_TRUE(copy.status.ok()) << copy.status.ToString();
  EXPECT_TRUE(copy.duplicate);
  EXPECT_EQ((*map)->Counts().places, 1);
}

// Robot "b" drives robot "a"'s street again an hour later, and its third frame fails to be
// stored. That frame's matches must not support b's later frames (sequence_support.h): like a
// query's, they are not remembered. They were, although nothing of the frame was kept.
TEST(RecognizerTest, AFrameThatWasNotStoredSupportsNoLaterFrame) {
  const cv::Mat world = World(5);
  const RecognizerOptions options = TestOptions();
  // The best match of b's fourth frame after b's third failed to be stored (kFail) or was a
  // query (kQuery).
  enum class Third { kFail, kQuery };
  auto last_match = [&](Third third) {
    StatusOr<std::unique_ptr<LandmarkStore>> inner = OpenSqliteStore(":memory:", {});
    EXPECT_TRUE(inner.ok());
    auto failing = std::make_unique<FailingStore>(std::move(*inner));
    FailingStore* store = failing.get();
    StatusOr<std::unique_ptr<PlaceMap>> map = PlaceMap::Open(std::move(failing), options.index);
    EXPECT_TRUE(map.ok()) << map.status().ToString();
    Recognizer recognizer(options, map->get());
    for (int i = 0; i < 6; ++i) {
      const RecognitionResult result =
          recognizer.Process({"a", i, i * 1000000LL, true}, View(world, i * kStep));
      EXPECT_TRUE(result.status.ok()) << result.status.ToString();
    }
    const int64_t later = 3600 * 1000000LL;
    RecognitionResult result;
    for (int i = 0; i < 4; ++i) {
      const bool insert = !(i == 2 && third == Third::kQuery);
      if (i == 2 && third == Third::kFail) store->FailNext();
      result = recognizer.Process({"b", i, later + i * 1000000LL, insert}, View(world, i * kStep));
      if (i == 2 && third == Third::kFail) {
        EXPECT_EQ(result.status.code(), StatusCode::kIoError);
      } else {
        EXPECT_TRUE(result.status.ok()) << result.status.ToString();
      }
    }
    EXPECT_FALSE(result.matches.empty());
    return result.matches.empty() ? PlaceMatch() : result.matches.front();
  };
  const PlaceMatch failed = last_match(Third::kFail);
  const PlaceMatch queried = last_match(Third::kQuery);
  EXPECT_EQ(failed.place.sequence, queried.place.sequence);
  EXPECT_EQ(failed.supporting_frames, queried.supporting_frames);
  EXPECT_DOUBLE_EQ(failed.score, queried.score);
}

// Checks come before any work: ids of 1..64 printable bytes, and for inserts a sequence after
// the robot's last one. Validate itself changes nothing.
TEST(RecognizerTest, ValidateNamesWhatIsWrong) {
  const RecognizerOptions options = TestOptions();
  std::unique_ptr<PlaceMap> map = OpenMap(":memory:", options);
  Recognizer recognizer(options, map.get());
  EXPECT_TRUE(recognizer.Validate({std::string(kMaxRobotIdLength, 'r'), 0, 0, true}).ok());
  const Status long_id = recognizer.Validate({std::string(kMaxRobotIdLength + 1, 'r'), 0, 0, true});
  EXPECT_EQ(long_id.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(long_id.message(), "robot id is 65 bytes; the limit is 64");
  EXPECT_EQ(recognizer.Validate({"", 0, 0, false}).message(), "robot id is empty");
  for (const std::string& robot :
       {std::string("ro\tbot"), std::string("ro\x7f"), std::string("a\0b", 3)}) {
    const Status bad = recognizer.Validate({robot, 0, 0, true});
    EXPECT_EQ(bad.code(), StatusCode::kInvalidArgument);
    EXPECT_EQ(bad.message(), "robot id contains a control character");
  }
  for (const int64_t utime : {int64_t{-1}, std::numeric_limits<int64_t>::min(), kMaxUtime + 1}) {
    const Status bad = recognizer.Validate({"a", 0, utime, false});
    EXPECT_EQ(bad.code(), StatusCode::kInvalidArgument) << utime;
    EXPECT_NE(bad.message().find("capture time"), std::string::npos) << bad.message();
  }
  EXPECT_TRUE(recognizer.Validate({"a", 0, kMaxUtime, false}).ok());
  // Validating does not take the sequence number; inserting does.
  EXPECT_TRUE(recognizer.Validate({"a", 3, 0, true}).ok());
  EXPECT_TRUE(recognizer.Validate({"a", 3, 0, true}).ok());
  const TwoFrames frames(43);
  ASSERT_TRUE(recognizer.Recognize({"a", 3, 0, true}, frames.First()).status.ok());
  const Status again = recognizer.Validate({"a", 3, 0, true});
  EXPECT_EQ(again.message(), "sequence 3 of robot 'a' is not after 3");
  // A rejected frame reports the map as it is.
  const RecognitionResult rejected = recognizer.Recognize({"a", 2, 0, true}, frames.Second());
  EXPECT_EQ(rejected.status.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(rejected.landmarks, 0);
  EXPECT_EQ(rejected.map.places, map->Counts().places);
  // Another robot has its own sequence.
  EXPECT_TRUE(recognizer.Validate({"b", 0, 0, true}).ok());
}

// Robot "b" sees the object robot "a" stored: every object is looked up by default, so b's
// first frame finds a's place; with QueryObjects::kLandmarks only b's landmarks are, so the
// first frame finds nothing and the second finds a's place through its landmark, reported with
// its index among the frame's objects.
TEST(RecognizerTest, OtherRobotsFindStoredLandmarksThroughTheQueriedObjects) {
  for (const QueryObjects which : {QueryObjects::kAll, QueryObjects::kLandmarks}) {
    const bool all = which == QueryObjects::kAll;
    SCOPED_TRACE(all ? "every object" : "landmarks only");
    TwoFrames frames(44);
    RecognizerOptions options = TestOptions();
    options.min_descriptors_per_place = 0;
    options.query_objects = which;
    options.loop.geometric_verification = false;  // random keypoint positions
    std::unique_ptr<PlaceMap> map = OpenMap(":memory:", options);
    Recognizer recognizer(options, map.get());
    ASSERT_TRUE(recognizer.Recognize({"a", 0, 0, true}, frames.First()).status.ok());
    const RecognitionResult stored = recognizer.Recognize({"a", 1, 1000000, true}, frames.Second());
    ASSERT_EQ(stored.landmarks, 1);
    ASSERT_TRUE(stored.place.IsValid());

    // b's frame 0: an unknown object D and A (the 12 tracked rows, seen again, and 8 others).
    std::mt19937& rng = frames.rng;
    const cv::Mat d = RandomDescriptors(20, &rng);
    const cv::Mat a_by_b =
        Rows({Noisy(frames.a.rowRange(0, 12), &rng), RandomDescriptors(8, &rng)});
    const RecognitionResult first =
        recognizer.Recognize({"b", 0, 0, true}, Observation({d, a_by_b}));
    ASSERT_TRUE(first.status.ok());
    if (all) {
      ASSERT_EQ(first.matches.size(), 1u);
      EXPECT_EQ(first.matches[0].place.id, stored.place);
      EXPECT_EQ(first.matches[0].place.robot, "a");
      EXPECT_EQ(first.matches[0].matched_descriptors, 12);
      EXPECT_EQ(
          first.matches[0].object_pairs,
          (std::vector<std::pair<int, LandmarkId>>{{1, first.matches[0].object_pairs[0].second}}));
    } else {
      EXPECT_TRUE(first.matches.empty());
    }
    // b's frame 1: two unknown objects, then A once more: A is b's landmark, object 2.
    const cv::Mat a_once_more = Noisy(a_by_b, &rng);
    const RecognitionResult second = recognizer.Recognize(
        {"b", 1, 1000000, true},
        Observation({RandomDescriptors(20, &rng), RandomDescriptors(20, &rng), a_once_more}));
    ASSERT_TRUE(second.status.ok());
    EXPECT_EQ(second.landmarks, 1);
    ASSERT_FALSE(second.matches.empty());
    EXPECT_EQ(second.matches[0].place.id, stored.place);
    ASSERT_EQ(second.matches[0].object_pairs.size(), 1u);
    EXPECT_EQ(second.matches[0].object_pairs[0].first, 2);
  }
}

// max_query_descriptors searches only the frame's strongest keypoints: here the first 10 rows of
// the object showing the stored landmark, so 10 of its 12 matches remain.
TEST(RecognizerTest, LooksUpOnlyTheStrongestDescriptorsWhenCapped) {
  for (const int cap : {0, 10}) {
    SCOPED_TRACE("max_query_descriptors " + std::to_string(cap));
    TwoFrames frames(45);
    RecognizerOptions options = TestOptions();
    options.min_descriptors_per_place = 0;
    options.max_query_descriptors = cap;
    options.loop.geometric_verification = false;
    std::unique_ptr<PlaceMap> map = OpenMap(":memory:", options);
    Recognizer recognizer(options, map.get());
    ASSERT_TRUE(recognizer.Recognize({"a", 0, 0, true}, frames.First()).status.ok());
    ASSERT_EQ(recognizer.Recognize({"a", 1, 1000000, true}, frames.Second()).landmarks, 1);
    std::mt19937& rng = frames.rng;
    // The stored rows first (strongest), then another object.
    const cv::Mat a_by_b =
        Rows({Noisy(frames.a.rowRange(0, 12), &rng), RandomDescriptors(8, &rng)});
    const RecognitionResult found = recognizer.Recognize(
        {"b", 0, 0, false}, Observation({a_by_b, RandomDescriptors(20, &rng)}));
    ASSERT_TRUE(found.status.ok());
    ASSERT_EQ(found.matches.size(), 1u);
    EXPECT_EQ(found.matches[0].matched_descriptors, cap == 0 ? 12 : 10);
  }
}

}  // namespace
}  // namespace placerec
