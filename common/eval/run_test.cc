#include "common/eval/run.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "common/util/paths.h"

namespace placerec {
namespace {

namespace fs = std::filesystem;
// Inside a test body, plain `Run` names testing::Test::Run(); hence placerec::Run below.

// A fresh dataset directory with a runs/ folder, removed afterwards.
class RunTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = ::testing::TempDir() + "/placerec_run_test_" +
           ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::remove_all(dir_);
    fs::create_directories(dir_ + "/runs");
  }
  void TearDown() override { fs::remove_all(dir_); }

  void Write(const std::string& relative, const std::string& text) {
    std::ofstream out(dir_ + "/runs/" + relative);
    out << text;
  }
  // Two robots; frames 3 and 4 revisit 0 and 1 (frame 4 twice), frame 2 is new.
  void WriteGoodRun(const std::string& name) {
    Write(name + ".frames.csv",
          "frame,robot,image,utime_us\n"
          "0,a,a/0.jpg,100\n"
          "1,a,a/1.jpg,200\n"
          "2,b,/abs/b0.jpg,50\n"
          "3,b,b/1.jpg,50\n"
          "4,a,a/2.jpg,300\n");
    Write(name + ".positives.csv", "query,reference\n3,0\n4,0\n4,1\n");
  }
  std::string Error(const std::string& frames, const std::string& positives) {
    Write("bad.frames.csv", frames);
    Write("bad.positives.csv", positives);
    StatusOr<placerec::Run> run = LoadRun(dir_, "bad");
    EXPECT_FALSE(run.ok());
    return run.ok() ? "" : run.status().message();
  }

  std::string dir_;
};

constexpr char kFrames[] = "frame,robot,image,utime_us\n0,a,0.jpg,1\n1,a,1.jpg,2\n2,a,2.jpg,3\n";

TEST_F(RunTest, LoadsFramesPositivesAndRevisits) {
  WriteGoodRun("tiny");
  StatusOr<placerec::Run> run = LoadRun(dir_, "tiny");
  ASSERT_TRUE(run.ok()) << run.status().ToString();
  EXPECT_EQ(run->name, "tiny");
  EXPECT_EQ(run->dataset_dir, dir_);
  ASSERT_EQ(run->frames.size(), 5u);
  EXPECT_EQ(run->frames[1].frame, 1);
  EXPECT_EQ(run->frames[1].robot, "a");
  EXPECT_EQ(run->frames[1].image, dir_ + "/a/1.jpg");
  EXPECT_EQ(run->frames[1].utime, 200);
  EXPECT_EQ(run->frames[2].image, "/abs/b0.jpg");  // absolute paths stay as they are
  EXPECT_EQ(run->positives.size(), 3u);
  EXPECT_TRUE(run->IsPositive(4, 1));
  EXPECT_FALSE(run->IsPositive(1, 4));
  EXPECT_FALSE(run->IsPositive(3, 1));
  EXPECT_EQ(run->is_revisit, (std::vector<bool>{false, false, false, true, true}));
  EXPECT_EQ(run->num_revisits, 2);
}

TEST_F(RunTest, ListsRunsSortedAndNamesThemWhenOneIsMissing) {
  WriteGoodRun("zeta");
  WriteGoodRun("alpha");
  Write("notes.txt", "not a run");
  EXPECT_EQ(ListRuns(dir_), (std::vector<std::string>{"alpha", "zeta"}));
  EXPECT_TRUE(ListRuns(dir_ + "/nope").empty());

  StatusOr<placerec::Run> run = LoadRun(dir_, "beta");
  ASSERT_FALSE(run.ok());
  EXPECT_EQ(run.status().code(), StatusCode::kNotFound);
  EXPECT_EQ(run.status().message(),
            "run 'beta' not found in " + dir_ + "/runs; available runs: alpha, zeta");
  run = LoadRun(dir_ + "/nope", "beta");
  ASSERT_FALSE(run.ok());
  EXPECT_NE(run.status().message().find(dir_ + "/nope/runs does not exist"), std::string::npos);
}

TEST_F(RunTest, AcceptsARunWithoutRevisits) {
  Write("flat.frames.csv", kFrames);
  Write("flat.positives.csv", "query,reference\r\n");
  StatusOr<placerec::Run> run = LoadRun(dir_, "flat");
  ASSERT_TRUE(run.ok()) << run.status().ToString();
  EXPECT_EQ(run->num_revisits, 0);
  EXPECT_EQ(run->is_revisit, std::vector<bool>(3, false));
}

TEST_F(RunTest, RejectsMalformedFilesNamingTheLine) {
  const std::string frames = dir_ + "/runs/bad.frames.csv";
  const std::string positives = dir_ + "/runs/bad.positives.csv";
  const std::string ok_positives = "query,reference\n2,0\n";

  EXPECT_EQ(Error("frame,robot,image\n0,a,0.jpg\n", ok_positives),
            frames +
                ":1: header has no 'utime_us' column; the header must be "
                "frame,robot,image,utime_us");
  EXPECT_EQ(Error("frame,robot,image,utime_us\n0,a,0.jpg,1\n1,a,1.jpg\n", ok_positives),
            frames +
                ":3: expected 4 fields (frame,robot,image,utime_us), found 3; fields are "
                "separated by commas and may not contain one");
  EXPECT_EQ(
      Error("frame,robot,image,utime_us\n0,a,0.jpg,1\n\n2,a,2.jpg,3\n1,a,1.jpg,4\n", ok_positives),
      frames +
          ":4: frame is 2, expected 1; frames must be numbered 0, 1, 2, ... in file "
          "order");
  EXPECT_EQ(Error("frame,robot,image,utime_us\n0,a,0.jpg,1\n1,,1.jpg,2\n", ok_positives),
            frames + ":3: robot is empty; give every frame the id of the robot that captured it");
  EXPECT_EQ(Error("frame,robot,image,utime_us\n0,a,0.jpg,1\n1,a,1.jpg,1.5\n", ok_positives),
            frames + ":3: utime_us '1.5' is not an integer (microseconds since the epoch)");
  EXPECT_EQ(
      Error("frame,robot,image,utime_us\n0,a,0.jpg,5\n1,b,1.jpg,1\n2,a,2.jpg,4\n", ok_positives),
      frames +
          ":4: utime_us 4 of robot 'a' is earlier than 5 on line 2; each robot's "
          "frames must be listed in capture order");
  EXPECT_EQ(Error(kFrames, "query,reference\n2,0\n1,1\n"),
            positives +
                ":3: reference 1 is not earlier than query 1; list each pair once, as "
                "(later frame, earlier frame)");
  EXPECT_EQ(Error(kFrames, "query,reference\n0,2\n"),
            positives +
                ":2: reference 2 is not earlier than query 0; list each pair once, as "
                "(later frame, earlier frame)");
  EXPECT_EQ(Error(kFrames, "query,reference\n2,0\n7,1\n"),
            positives + ":3: frame 7 does not exist; the frames file lists frames 0..2");
  EXPECT_EQ(Error(kFrames, "query,reference\n2,x\n"),
            positives + ":2: reference 'x' is not an integer");
  EXPECT_EQ(Error("frame,robot,image,utime_us\n", ok_positives),
            frames + " has a header but no frames; a run needs at least one");

  Write("bad.frames.csv", kFrames);
  fs::remove(positives);
  StatusOr<placerec::Run> run = LoadRun(dir_, "bad");
  ASSERT_FALSE(run.ok());
  EXPECT_EQ(run.status().code(), StatusCode::kNotFound);
  EXPECT_NE(run.status().message().find(positives + " does not exist"), std::string::npos);
}

// A dataset is a folder, or a name under the data root; a name that is neither is told with
// where it was looked for and the datasets the root holds.
TEST_F(RunTest, FindDatasetByFolderOrNameAndListsTheRootOtherwise) {
  const std::string root = dir_ + "/data";
  fs::create_directories(root + "/gardens_point");
  fs::create_directories(root + "/rtabmap_indoor");
  std::ofstream(root + "/README.md") << "not a dataset";
  EXPECT_EQ(*FindDataset("rtabmap_indoor", root), root + "/rtabmap_indoor");
  EXPECT_EQ(*FindDataset(dir_, root), dir_);
  const StatusOr<std::string> misspelt = FindDataset("rtabmap_indor", root);
  ASSERT_FALSE(misspelt.ok());
  EXPECT_EQ(misspelt.status().code(), StatusCode::kNotFound);
  EXPECT_NE(misspelt.status().message().find(root), std::string::npos);
  EXPECT_NE(misspelt.status().message().find("datasets there: gardens_point, rtabmap_indoor"),
            std::string::npos)
      << misspelt.status().message();
  EXPECT_FALSE(FindDataset("README.md", root).ok());  // a file is no dataset
  EXPECT_NE(FindDataset("x", dir_ + "/nowhere").status().message().find("does not exist"),
            std::string::npos);
  fs::create_directories(dir_ + "/empty");
  EXPECT_NE(FindDataset("x", dir_ + "/empty").status().message().find("holds no datasets"),
            std::string::npos);
}

TEST(FirstFramesTest, KeepsOnlyTheRevisitsOfTheFramesKept) {
  // Ten frames; revisits 5 (of 0 and 1), 6 (of 1), 7 (of 2), 8 (of 3).
  placerec::Run run;
  for (int i = 0; i < 10; ++i) run.frames.push_back({i, "r", "f.jpg", i});
  run.positives = {{5, 0}, {5, 1}, {6, 1}, {7, 2}, {8, 3}};
  run.is_revisit = {false, false, false, false, false, true, true, true, true, false};
  run.num_revisits = 4;
  const placerec::Run cut = FirstFrames(run, 7);
  EXPECT_EQ(cut.frames.size(), 7u);
  EXPECT_EQ(cut.positives, (std::set<std::pair<int, int>>{{5, 0}, {5, 1}, {6, 1}}));
  EXPECT_EQ(cut.num_revisits, 2);
  EXPECT_EQ(cut.is_revisit, (std::vector<bool>{false, false, false, false, false, true, true}));
  EXPECT_EQ(FirstFrames(run, 10).num_revisits, 4);
  EXPECT_EQ(FirstFrames(run, 0).num_revisits, 0);
}

// Every run in the shared evaluation data loads and has the counts ../shared/data/README.md
// states.
TEST(RealDataTest, EveryRunLoadsWithTheDocumentedCounts) {
  const std::string data = DataDir("", PLACEREC_DEFAULT_DATA_DIR);
  if (!PathExists(data + "/gardens_point/runs") || !PathExists(data + "/rtabmap_indoor/runs")) {
    GTEST_SKIP() << "evaluation data not found: " << data
                 << " has no gardens_point/runs or rtabmap_indoor/runs; set PLACEREC_DATA to the "
                    "folder that holds them (the project's ../shared/data)";
  }
  struct Expected {
    std::string dataset;
    std::string run;
    int frames;
    int revisits;
  };
  const std::vector<Expected> expected = {
      {"gardens_point", "day_left_then_day_right", 400, 200},
      {"gardens_point", "day_left_then_night_right", 400, 200},
      {"gardens_point", "day_right_then_night_right", 400, 200},
      {"rtabmap_indoor", "corridor_loop", 84, 44},
  };
  EXPECT_EQ(ListRuns(data + "/gardens_point"),
            (std::vector<std::string>{"day_left_then_day_right", "day_left_then_night_right",
                                      "day_right_then_night_right"}));
  EXPECT_EQ(ListRuns(data + "/rtabmap_indoor"), (std::vector<std::string>{"corridor_loop"}));
  for (const Expected& e : expected) {
    SCOPED_TRACE(e.dataset + "/" + e.run);
    StatusOr<placerec::Run> run = LoadRun(data + "/" + e.dataset, e.run);
    ASSERT_TRUE(run.ok()) << run.status().ToString();
    EXPECT_EQ(static_cast<int>(run->frames.size()), e.frames);
    EXPECT_EQ(run->num_revisits, e.revisits);
    EXPECT_TRUE(PathExists(run->frames.front().image)) << run->frames.front().image;
    EXPECT_TRUE(PathExists(run->frames.back().image)) << run->frames.back().image;
  }
}

}  // namespace
}  // namespace placerec
