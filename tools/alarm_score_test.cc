#include "tools/alarm_score.h"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

namespace placerec {
namespace {

ChangeCase Case(int frame, ChangeCase::Kind kind, const cv::Rect& truth = cv::Rect()) {
  ChangeCase c;
  c.frame = frame;
  c.robot = "right";
  c.utime = 1000 + frame;
  c.kind = kind;
  c.truth = truth;
  c.frame_size = cv::Size(100, 100);
  return c;
}

WatchedAlarm Alarm(const std::string& robot, int64_t sequence, const cv::Rect& box,
                   const cv::Size& frame_size = cv::Size(100, 100)) {
  WatchedAlarm a;
  a.robot = robot;
  a.sequence = sequence;
  a.box = box;
  a.frame_size = frame_size;
  a.confidence = 0.7;
  return a;
}

// Alarms are matched with revisits by robot and sequence number, and scored as
// `placerec-eval change` scores its answers.
TEST(AlarmScoreTest, HitsMissesFalseAlarmsAndAlarmsElsewhere) {
  using Kind = ChangeCase::Kind;
  const std::vector<ChangeCase> cases = {
      Case(10, Kind::kPasted, cv::Rect(0, 0, 20, 20)),    // 4 %: found
      Case(11, Kind::kPasted, cv::Rect(50, 50, 12, 12)),  // 1.44 %: boxed far off
      Case(12, Kind::kPasted, cv::Rect(0, 0, 30, 30)),    // 9 %: no alarm
      Case(13, Kind::kRemoved, cv::Rect(60, 0, 20, 20)),  // found
      Case(14, Kind::kUnchanged),                         // an alarm: false
      Case(15, Kind::kUnchanged),                         // quiet
      // A change that could not be made: the frame went unchanged, but it is no unchanged
      // revisit of the design either (its alarm is neither a hit nor false).
      Case(16, Kind::kNotMade),
  };
  const std::vector<WatchedAlarm> alarms = {
      Alarm("right", 10, cv::Rect(2, 2, 20, 20)),
      Alarm("right", 10, cv::Rect(70, 70, 5, 5)),
      Alarm("right", 11, cv::Rect(0, 0, 12, 12)),
      Alarm("right", 14, cv::Rect(5, 5, 10, 10)),
      Alarm("left", 12, cv::Rect(0, 0, 30, 30)),
      Alarm("right", 99, cv::Rect(5, 5, 10, 10)),
      // Frame 13 sent at half size: its box in the case's pixels is the true one.
      Alarm("right", 13, cv::Rect(30, 0, 10, 10), cv::Size(50, 50)),
      Alarm("right", 16, cv::Rect(5, 5, 10, 10)),
  };
  const nlohmann::json j = ScoreAlarms(cases, alarms, 0.3);
  EXPECT_EQ(j["appeared"]["cases"], 3);
  EXPECT_EQ(j["appeared"]["found"], 1);
  EXPECT_DOUBLE_EQ(j["detection_recall"].get<double>(), 1.0 / 3);
  EXPECT_DOUBLE_EQ(j["detection_recall_2pct"].get<double>(), 0.5);  // 1 of frames 10 and 12
  EXPECT_EQ(j["appeared"]["by_size"]["<2%"]["cases"], 1);
  EXPECT_NEAR(j["localisation_iou"].get<double>(), 324.0 / 476.0, 1e-9);
  EXPECT_EQ(j["removed"]["found"], 1);
  EXPECT_EQ(j["unchanged"], 2);
  EXPECT_EQ(j["false_alarms"], 1);
  EXPECT_DOUBLE_EQ(j["false_alarm_rate"].get<double>(), 0.5);
  EXPECT_EQ(j["changes_not_made"], 1);
  EXPECT_EQ(j["alarms"], 8);
  EXPECT_EQ(j["removed"]["localisation_iou_median"], 1.0);
  // Robot "left"'s frame 12 and "right"'s frame 99 are no revisit of the cases.
  EXPECT_EQ(j["frames_alarmed_elsewhere"], 2);
  EXPECT_FALSE(j["appeared"].contains("compared"));
}

// The size bands count the object's share of the frame, not its box's: an object covering 1.5 %
// whose box covers 4 % is no object of at least 2 % (the box was counted, so thin or round objects
// under 2 % entered the ">= 2 %" recall).
TEST(AlarmScoreTest, SizeBandsCountTheObjectNotItsBox) {
  ChangeCase thin = Case(20, ChangeCase::Kind::kPasted, cv::Rect(0, 0, 20, 20));  // box 4 %
  thin.area_share = 0.015;
  const nlohmann::json j = ScoreAlarms({thin}, {Alarm("right", 20, cv::Rect(0, 0, 20, 20))}, 0.3);
  EXPECT_EQ(j["appeared"]["found"], 1);
  EXPECT_EQ(j["appeared"]["by_size"]["<2%"]["cases"], 1);
  EXPECT_EQ(j["appeared"]["by_size"]["2-5%"]["cases"], 0);
}

TEST(AlarmScoreTest, ChangesFileReadsAndRefusesWhatIsWrong) {
  const std::string path = ::testing::TempDir() + "/placerec_alarm_score_test_changes.csv";
  const std::string header =
      "frame,robot,utime_us,case,x,y,width,height,frame_width,frame_height,object_class\n";
  std::ofstream(path) << header << "3,right,1003,pasted,1,2,30,40,640,480,Car\n"
                      << "5,right,1005,unchanged,0,0,0,0,640,480,\n"
                      << "6,right,1006,not_made,0,0,0,0,640,480,\n";
  StatusOr<std::vector<ChangeCase>> read = LoadChangeCases(path);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  ASSERT_EQ(read->size(), 3u);
  EXPECT_EQ((*read)[0].kind, ChangeCase::Kind::kPasted);
  EXPECT_EQ((*read)[0].truth, cv::Rect(1, 2, 30, 40));
  EXPECT_EQ((*read)[0].frame_size, cv::Size(640, 480));
  EXPECT_EQ((*read)[0].object_class, "Car");
  EXPECT_EQ((*read)[1].kind, ChangeCase::Kind::kUnchanged);
  EXPECT_EQ((*read)[2].kind, ChangeCase::Kind::kNotMade);

  std::ofstream(path) << header << "3,right,1003,moved,1,2,30,40,640,480,\n";
  EXPECT_NE(LoadChangeCases(path).status().message().find(path + ":2: case 'moved'"),
            std::string::npos);
  std::ofstream(path) << header << "3,right,1003,pasted,0,0,0,0,640,480,\n";
  EXPECT_NE(LoadChangeCases(path).status().message().find("needs its box"), std::string::npos);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace placerec
