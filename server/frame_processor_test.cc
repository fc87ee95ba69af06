// Tests of the frame processor (frame_processor.h) in-process, on raw frames of the pipeline
// tests' synthetic street: the sequence rule of issue 23 item 3 as a robot meets it (a forged
// sequence far ahead, its own restart, a server restart in between).
#include "server/frame_processor.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <memory>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "common/pipeline/pipeline_test_util.h"
#include "common/storage/sqlite_store.h"
#include "common/storage/storage_testing.h"

namespace placerec {
namespace {

using pipeline_test::kStep;
using pipeline_test::SyntheticAnalyzerOptions;
using pipeline_test::View;
using pipeline_test::World;

RecognizerOptions TestOptions() {
  RecognizerOptions options;
  options.analyzer = SyntheticAnalyzerOptions();
  return options;
}

std::unique_ptr<PlaceMap> OpenMap(const std::string& path) {
  StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(path, SqliteStoreOptions());
  EXPECT_TRUE(store.ok()) << store.status().ToString();
  StatusOr<std::unique_ptr<PlaceMap>> map = PlaceMap::Open(std::move(*store), TestOptions().index);
  EXPECT_TRUE(map.ok()) << map.status().ToString();
  return std::move(*map);
}

std::unique_ptr<FrameProcessor> NewProcessor(PlaceMap* map, double restart_gap_s) {
  SequenceRuleOptions rule;
  rule.restart_gap_s = restart_gap_s;
  return std::make_unique<FrameProcessor>(TestOptions(), DecodeOptions(), map, nullptr, rule);
}

// Frame `sequence` of robot `robot`: the view `step` steps along the street, as raw BGR.
frame_t Frame(const std::string& robot, int64_t sequence, int step) {
  static const cv::Mat world = World(3);
  const cv::Mat view = View(world, step * kStep);
  frame_t frame;
  frame.utime = 1000000 * (step + 1);
  frame.sequence = sequence;
  frame.request_id = sequence;
  frame.insert = true;
  frame.encoding = frame_t::ENCODING_RAW_BGR8;
  frame.width = view.cols;
  frame.height = view.rows;
  frame.robot = robot;
  frame.data.assign(view.data, view.data + view.total() * view.elemSize());
  frame.size = static_cast<int32_t>(frame.data.size());
  return frame;
}

class TempMap {
 public:
  TempMap()
      : path_(::testing::TempDir() + "/placerec_frame_processor_" + std::to_string(getpid()) +
              ".db") {
    Remove();
  }
  ~TempMap() { Remove(); }
  const std::string& path() const { return path_; }

 private:
  void Remove() {
    for (const char* suffix : {"", "-wal", "-shm"}) std::remove((path_ + suffix).c_str());
  }
  std::string path_;
};

// A segmenter that fails as OpenCV does when given arrays it cannot combine.
class ThrowingSegmenter : public Segmenter {
 public:
  SceneSegmentation Segment(const WorkingImage&, cv::Mat*, TextonMap*) const override {
    cv::Mat a(2, 2, CV_8U, cv::Scalar(1)), b(2, 2, CV_32F, cv::Scalar(1));
    cv::Mat sum;
    cv::add(a, b, sum);  // throws: different types and no output type
    return SceneSegmentation();
  }
  std::string name() const override { return "throwing"; }
  int working_width() const override { return 160; }
};

// An exception inside the pipeline is answered "internal error" with the stage it left: a
// library's message names only its own function (the soak's one such answer said only
// "arithm_op"). The processor goes on with the next frame.
TEST(FrameProcessorTest, AnInternalErrorNamesTheStageItHappenedIn) {
  TempMap temp;
  std::unique_ptr<PlaceMap> map = OpenMap(temp.path());
  FrameProcessor processor(TestOptions(), DecodeOptions(), map.get(),
                           std::make_unique<ThrowingSegmenter>(), SequenceRuleOptions());
  const result_t answer = processor.Process(Frame("r", 0, 0), nullptr);
  EXPECT_EQ(answer.status, int{result_t::STATUS_INTERNAL_ERROR});
  EXPECT_NE(answer.message.find("(in analyze > segmentation)"), std::string::npos)
      << answer.message;
  EXPECT_NE(answer.message.find("arithm_op"), std::string::npos) << answer.message;
  EXPECT_EQ(map->Counts().places, 0);
}

std::vector<std::string> Sorted(std::vector<std::string> robots) {
  std::sort(robots.begin(), robots.end());
  return robots;
}

// Each robot id that ever inserted kept its run (about a megabyte of short-term memory) for good,
// so a server that sees ever new ids grew without bound. Now at most max_robot_runs runs are
// kept; the robot silent longest loses its run, and a robot that comes back begins a new one.
TEST(FrameProcessorTest, RunsOfAtMostMaxRobotsAreKeptAndTheRobotSilentLongestIsForgotten) {
  std::unique_ptr<PlaceMap> map = OpenMap(":memory:");
  SequenceRuleOptions rule;
  rule.max_robot_runs = 2;
  FrameProcessor processor(TestOptions(), DecodeOptions(), map.get(), nullptr, rule);
  auto insert = [&](const std::string& robot, int64_t sequence) {
    const result_t answer = processor.Process(Frame(robot, sequence, static_cast<int>(sequence)));
    EXPECT_EQ(int{answer.status}, int{result_t::STATUS_OK})
        << robot << " " << sequence << ": " << answer.message;
  };
  insert("a", 0);
  insert("b", 0);
  insert("a", 1);  // b is now the robot silent longest
  EXPECT_EQ(Sorted(processor.RobotsWithRuns()), (std::vector<std::string>{"a", "b"}));
  insert("c", 0);
  EXPECT_EQ(Sorted(processor.RobotsWithRuns()), (std::vector<std::string>{"a", "c"}));
  // b comes back: answered as before, with a new run; a is now the one silent longest.
  insert("b", 1);
  EXPECT_EQ(Sorted(processor.RobotsWithRuns()), (std::vector<std::string>{"b", "c"}));
  // Query-only frames of a robot without a run are answered and keep no run.
  frame_t query = Frame("d", 0, 1);
  query.insert = false;
  EXPECT_EQ(int{processor.Process(query).status}, int{result_t::STATUS_OK});
  EXPECT_EQ(Sorted(processor.RobotsWithRuns()), (std::vector<std::string>{"b", "c"}));
}

// A robot that stands still while the server restarts (or forgets its run) kept sending the same
// view; the new run's recent past was empty, so once its last place was older than the recent
// past's minimum gap (20 s) that place answered it as a loop closure: its own recent past. Now
// the robot's stored places of the last ten minutes are its views again. Without that
// (resume_within_seconds 0, the old behaviour) the robot's own place answers it: the test can
// tell.
TEST(FrameProcessorTest, ARobotThatStoodStillAcrossARestartIsNotAnsweredWithItsOwnPlace) {
  for (const bool resume : {true, false}) {
    SCOPED_TRACE(resume ? "resuming" : "not resuming");
    RecognizerOptions options = TestOptions();
    if (!resume) options.recent_past.resume_within_seconds = 0;
    TempMap file;
    {
      std::unique_ptr<PlaceMap> map = OpenMap(file.path());
      FrameProcessor processor(options, DecodeOptions(), map.get());
      for (int s = 0; s < 4; ++s) {
        const result_t answer = processor.Process(Frame("r", s, s));
        ASSERT_EQ(int{answer.status}, int{result_t::STATUS_OK}) << answer.message;
      }
      ASSERT_GT(map->Counts().places, 0);
    }
    // A minute later, the same view as the last frame, through a restarted server.
    std::unique_ptr<PlaceMap> map = OpenMap(file.path());
    FrameProcessor processor(options, DecodeOptions(), map.get());
    frame_t still = Frame("r", 4, 3);
    still.utime += 60 * 1000000LL;
    const result_t answer = processor.Process(still);
    ASSERT_EQ(int{answer.status}, int{result_t::STATUS_OK}) << answer.message;
    const bool own =
        answer.loop_closure && answer.num_matches > 0 && answer.matches[0].robot == "r";
    EXPECT_EQ(own, !resume) << "loop closure " << answer.loop_closure << ", " << answer.num_matches
                            << " matches";
  }
}

// The attack of issue 23 item 3: one insert with sequence 2^63-1 made every later insert of the
// robot fail until the server restarted. Now the robot is refused for the restart gap only, and
// the forged place keeps its sequence.
TEST(FrameProcessorTest, AForgedSequenceLocksTheRobotOutOnlyForTheRestartGap) {
  std::unique_ptr<PlaceMap> map = OpenMap(":memory:");
  std::unique_ptr<FrameProcessor> processor = NewProcessor(map.get(), 1.0);
  for (int s = 0; s < 2; ++s) {
    const result_t answer = processor->Process(Frame("r", s, s));
    ASSERT_EQ(int{answer.status}, int{result_t::STATUS_OK}) << answer.message;
  }
  const int64_t forged_sequence = std::numeric_limits<int64_t>::max();
  const result_t forged = processor->Process(Frame("r", forged_sequence, 5));
  ASSERT_EQ(int{forged.status}, int{result_t::STATUS_OK}) << forged.message;
  const result_t locked = processor->Process(Frame("r", 2, 2));
  EXPECT_EQ(int{locked.status}, int{result_t::STATUS_BAD_REQUEST});
  EXPECT_NE(locked.message.find("is not after 9223372036854775807"), std::string::npos)
      << locked.message;
  EXPECT_NE(locked.message.find("1 s after its last accepted frame"), std::string::npos)
      << locked.message;
  EXPECT_EQ(locked.map_places, forged.map_places);  // the refusal changed nothing

  std::this_thread::sleep_for(std::chrono::milliseconds(1100));
  for (int s = 2; s < 4; ++s) {
    const result_t answer = processor->Process(Frame("r", s, s));
    EXPECT_EQ(int{answer.status}, int{result_t::STATUS_OK})
        << "sequence " << s << ": " << answer.message;
  }
}

// A robot that restarts numbers its frames from 0 again; the server restarted in between. The
// robot's last sequence comes back from the map, and a sequence the map holds is refused with the
// one to continue from, after all the robot's sequences, which the robot can then use.
TEST(FrameProcessorTest, LastSequencesSurviveARestartAndStoredOnesAreNeverReused) {
  TempMap file;
  std::vector<int64_t> stored;
  {
    std::unique_ptr<PlaceMap> map = OpenMap(file.path());
    std::unique_ptr<FrameProcessor> processor = NewProcessor(map.get(), 3600);
    for (int s = 0; s < 4; ++s) {
      const result_t answer = processor->Process(Frame("r", s, s));
      ASSERT_EQ(int{answer.status}, int{result_t::STATUS_OK}) << answer.message;
      if (answer.place_id >= 0) stored.push_back(s);
    }
  }
  ASSERT_FALSE(stored.empty());
  const int64_t first_stored = stored.front();
  const int64_t next = stored.back() + 1;  // a restarted server knows the stored ones
  {
    // Restarted server, restart gap of an hour: the order still holds.
    std::unique_ptr<PlaceMap> map = OpenMap(file.path());
    const int64_t places = map->Counts().places;
    std::unique_ptr<FrameProcessor> processor = NewProcessor(map.get(), 3600);
    // (Another capture time than the stored frame's: the same frame again would be a resend.)
    const result_t back = processor->Process(Frame("r", first_stored, 7));
    EXPECT_EQ(int{back.status}, int{result_t::STATUS_BAD_REQUEST});
    EXPECT_NE(back.message.find("is not after " + std::to_string(stored.back())), std::string::npos)
        << back.message;
    EXPECT_EQ(map->Counts().places, places);
  }
  {
    // Restarted server, no restart gap: the robot restarts at a stored sequence and is told the
    // one after all its sequences, which is accepted.
    std::unique_ptr<PlaceMap> map = OpenMap(file.path());
    const int64_t places = map->Counts().places;
    std::unique_ptr<FrameProcessor> processor = NewProcessor(map.get(), 0);
    const result_t reused = processor->Process(Frame("r", first_stored, 7));
    EXPECT_EQ(int{reused.status}, int{result_t::STATUS_BAD_REQUEST});
    EXPECT_NE(reused.message.find("already in the map"), std::string::npos) << reused.message;
    EXPECT_NE(reused.message.find("continue from " + std::to_string(next)), std::string::npos)
        << reused.message;
    EXPECT_EQ(reused.next_sequence, next);  // the same number, for a program to read
    EXPECT_EQ(map->Counts().places, places);
    const result_t resumed = processor->Process(Frame("r", next, 6));
    EXPECT_EQ(int{resumed.status}, int{result_t::STATUS_OK}) << resumed.message;
    EXPECT_EQ(resumed.next_sequence, next + 1);
    // A query tells a known robot where to continue before it inserts anything ...
    frame_t ask = Frame("r", 0, 8);
    ask.insert = false;
    EXPECT_EQ(processor->Process(ask).next_sequence, next + 1);
    // ... and a robot the server knows no sequence of -1, on a query as on a refusal.
    frame_t query = Frame("new", 0, 8);
    query.insert = false;
    EXPECT_EQ(processor->Process(query).next_sequence, -1);
    EXPECT_EQ(processor->Process(Frame("", 0, 8)).next_sequence, -1);
  }
}

// A server killed after it committed an insert but before the answer went out: the robot sends
// the frame again (same robot, sequence and capture time) to the restarted server, which answers
// it ok with the stored place instead of "already in the map", and stores nothing twice. A
// different frame with a stored sequence is still refused.
TEST(FrameProcessorTest, AnInsertSentAgainAfterARestartIsAnsweredWithItsStoredPlace) {
  TempMap file;
  frame_t frame;
  int64_t place_id = -1;
  int landmarks = 0;
  int step = 0;
  {
    std::unique_ptr<PlaceMap> map = OpenMap(file.path());
    std::unique_ptr<FrameProcessor> processor = NewProcessor(map.get(), 5.0);
    for (; step < 4 && place_id < 0; ++step) {  // the first frame that stores a place
      frame = Frame("r", step, step);
      const result_t answer = processor->Process(frame);
      ASSERT_EQ(int{answer.status}, int{result_t::STATUS_OK}) << answer.message;
      place_id = answer.place_id;
      landmarks = answer.landmarks;
    }
    ASSERT_GE(place_id, 0);
  }
  std::unique_ptr<PlaceMap> map = OpenMap(file.path());
  std::unique_ptr<FrameProcessor> restarted = NewProcessor(map.get(), 1.0);
  const MapCounts before = map->Counts();
  for (const double wait_s : {0.0, 1.1}) {  // within the restart gap, and after it
    std::this_thread::sleep_for(std::chrono::milliseconds(static_cast<int>(wait_s * 1000)));
    frame.request_id = 7;
    const result_t again = restarted->Process(frame);
    EXPECT_EQ(int{again.status}, int{result_t::STATUS_OK}) << again.message;
    EXPECT_EQ(again.place_id, place_id);
    EXPECT_EQ(again.landmarks, landmarks);
    EXPECT_EQ(again.request_id, 7);
    EXPECT_EQ(again.map_places, before.places);
    EXPECT_EQ(map->Counts().landmarks, before.landmarks);
  }
  const frame_t other = Frame("r", frame.sequence, step + 1);  // another capture time
  const result_t refused = restarted->Process(other);
  EXPECT_EQ(int{refused.status}, int{result_t::STATUS_BAD_REQUEST});
  EXPECT_NE(refused.message.find("already in the map"), std::string::npos) << refused.message;
  // The robot goes on after it.
  EXPECT_EQ(int{restarted->Process(Frame("r", frame.sequence + 1, step)).status},
            int{result_t::STATUS_OK});
}

// A map written before capture times were checked may hold a place of a time out of range; the
// map uses it as 0 (or the largest time). No frame of such a time is accepted, so none can be that
// place sent again: a frame at time 0 with its robot and sequence is refused, not answered as it.
TEST(FrameProcessorTest, APlaceWhoseStoredTimeWasOutOfRangeIsNoCopyOfAFrameAtTimeZero) {
  TempMap file;
  {
    StatusOr<std::unique_ptr<LandmarkStore>> store =
        OpenSqliteStore(file.path(), SqliteStoreOptions());
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    Place old;
    old.robot = "r";
    old.sequence = 3;
    old.utime = 1;
    std::vector<Landmark> none;
    const Status added = (*store)->AddPlace(&old, &none);
    ASSERT_TRUE(added.ok()) << added.ToString();
  }
  testing_storage::ExecSql(file.path(), "UPDATE places SET utime = -5");
  std::unique_ptr<PlaceMap> map = OpenMap(file.path());
  std::unique_ptr<FrameProcessor> processor = NewProcessor(map.get(), 5.0);
  frame_t frame = Frame("r", 3, 0);
  frame.utime = 0;
  const result_t answer = processor->Process(frame);
  EXPECT_EQ(int{answer.status}, int{result_t::STATUS_BAD_REQUEST}) << answer.message;
  EXPECT_NE(answer.message.find("sequence 3 of robot 'r'"), std::string::npos) << answer.message;
  EXPECT_EQ(answer.place_id, -1);
  EXPECT_EQ(map->Counts().places, 1);
}

}  // namespace
}  // namespace placerec
