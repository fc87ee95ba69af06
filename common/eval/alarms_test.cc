#include "common/eval/alarms.h"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

namespace placerec {
namespace {

class AlarmsFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = ::testing::TempDir() + "/placerec_alarms_test_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name() + ".csv";
  }
  void TearDown() override { std::filesystem::remove(path_); }

  void Write(const std::string& text) { std::ofstream(path_) << text; }

  std::string path_;
};

TEST_F(AlarmsFileTest, LinesReadBackAsWritten) {
  WatchedAlarm a;
  a.robot = "site 3,robot%1";  // a comma and a percent sign survive the CSV
  a.sequence = 42;
  a.frame_utime = 1700000000123456;
  a.place_id = 7;
  a.place_robot = "left";
  a.place_utime = 1700000000000000;
  a.appeared = false;
  a.box = cv::Rect(10, 20, 30, 40);
  a.frame_size = cv::Size(640, 480);
  a.object_class = "car";
  a.confidence = 0.625;
  WatchedAlarm b;
  b.robot = "b";
  b.box = cv::Rect(1, 2, 3, 4);
  Write(WatchedAlarmHeader() + "\n" + WatchedAlarmLine(a) + "\n" + WatchedAlarmLine(b) + "\n");
  StatusOr<std::vector<WatchedAlarm>> read = LoadWatchedAlarms(path_);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  ASSERT_EQ(read->size(), 2u);
  const WatchedAlarm& r = (*read)[0];
  EXPECT_EQ(r.robot, a.robot);
  EXPECT_EQ(r.sequence, 42);
  EXPECT_EQ(r.frame_utime, a.frame_utime);
  EXPECT_EQ(r.place_id, 7);
  EXPECT_EQ(r.place_robot, "left");
  EXPECT_EQ(r.place_utime, a.place_utime);
  EXPECT_FALSE(r.appeared);
  EXPECT_EQ(r.box, a.box);
  EXPECT_EQ(r.frame_size, a.frame_size);
  EXPECT_EQ(r.object_class, "car");
  EXPECT_DOUBLE_EQ(r.confidence, 0.625);
  EXPECT_TRUE((*read)[1].appeared);
  EXPECT_EQ((*read)[1].object_class, "");
}

TEST_F(AlarmsFileTest, MalformedFilesAreNamed) {
  EXPECT_EQ(LoadWatchedAlarms(path_ + ".missing").status().code(), StatusCode::kNotFound);
  Write("robot,sequence\nb,1\n");
  const Status no_column = LoadWatchedAlarms(path_).status();
  EXPECT_EQ(no_column.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(no_column.message().find("no column 'frame_utime'"), std::string::npos);
  WatchedAlarm a;
  a.robot = "b";
  std::string line = WatchedAlarmLine(a);
  line.replace(line.find("appeared"), 8, "arrived");
  Write(WatchedAlarmHeader() + "\n" + line + "\n");
  const Status bad_kind = LoadWatchedAlarms(path_).status();
  EXPECT_EQ(bad_kind.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(bad_kind.message().find(path_ + ":2"), std::string::npos) << bad_kind.message();
}

TEST_F(AlarmsFileTest, ChangeCasesReadBackAsWritten) {
  ChangeCase pasted;
  pasted.frame = 41;
  pasted.robot = "site 3,robot";
  pasted.utime = 1300000041000000;
  pasted.kind = ChangeCase::Kind::kPasted;
  pasted.truth = cv::Rect(208, 6, 50, 65);
  pasted.frame_size = cv::Size(512, 384);
  pasted.object_class = "car";
  pasted.area_share = 0.0123457;
  ChangeCase unchanged;
  unchanged.frame = 42;
  unchanged.robot = "robot";
  Write(ChangeCaseHeader() + "\n" + ChangeCaseLine(pasted) + "\n" + ChangeCaseLine(unchanged) +
        "\n");
  StatusOr<std::vector<ChangeCase>> read = LoadChangeCases(path_);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  ASSERT_EQ(read->size(), 2u);
  const ChangeCase& r = (*read)[0];
  EXPECT_EQ(r.frame, 41);
  EXPECT_EQ(r.robot, pasted.robot);
  EXPECT_EQ(r.utime, pasted.utime);
  EXPECT_EQ(r.kind, ChangeCase::Kind::kPasted);
  EXPECT_EQ(r.truth, pasted.truth);
  EXPECT_EQ(r.frame_size, pasted.frame_size);
  EXPECT_EQ(r.object_class, "car");
  EXPECT_DOUBLE_EQ(r.area_share, 0.0123457);
  EXPECT_DOUBLE_EQ(r.AreaShare(), 0.0123457);  // the object's, not its box's
  EXPECT_EQ((*read)[1].kind, ChangeCase::Kind::kUnchanged);
  EXPECT_TRUE((*read)[1].truth.empty());
}

// A changes file of an older placerec has no area_share: the box's share stands in.
TEST_F(AlarmsFileTest, ChangeCasesWithoutAreaShareUseTheBox) {
  Write(
      "frame,robot,utime_us,case,x,y,width,height,frame_width,frame_height,object_class\n"
      "7,right,1007,pasted,0,0,20,10,100,100,car\n");
  StatusOr<std::vector<ChangeCase>> read = LoadChangeCases(path_);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  ASSERT_EQ(read->size(), 1u);
  EXPECT_EQ((*read)[0].area_share, 0);
  EXPECT_DOUBLE_EQ((*read)[0].AreaShare(), 0.02);
  Write(ChangeCaseHeader() + "\n7,right,1007,pasted,0,0,20,10,100,100,car,1.5\n");
  EXPECT_EQ(LoadChangeCases(path_).status().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace placerec
