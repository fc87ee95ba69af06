#include "common/recognition/sequence_support.h"

#include <limits>

#include <gtest/gtest.h>

namespace placerec {
namespace {

constexpr int64_t kSecond = 1000000;

// A place of `robot` taken at `seconds`, matched with single-frame score `score`.
PlaceMatch Match(const std::string& robot, int64_t seconds, double score) {
  PlaceMatch m;
  m.place.id = PlaceId(seconds + 1);
  m.place.robot = robot;
  m.place.utime = seconds * kSecond;
  m.score = score;
  m.frame_score = score;
  return m;
}

TEST(SequenceSupportTest, DefaultsPassAndBadValuesFail) {
  std::string error;
  EXPECT_TRUE(SequenceOptions().Check(&error)) << error;
  SequenceOptions bad;
  bad.frames = -1;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_NE(error.find("frames"), std::string::npos);
  bad = SequenceOptions();
  bad.tolerance_seconds = 0;
  EXPECT_FALSE(bad.Check(&error));
  bad = SequenceOptions();
  bad.max_age_seconds = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(bad.Check(&error));
  // An infinite spacing gave a negative one in microseconds.
  for (const double seconds :
       {1e13, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    bad = SequenceOptions();
    bad.min_spacing_seconds = seconds;
    EXPECT_FALSE(bad.Check(&error)) << seconds;
    bad = SequenceOptions();
    bad.tolerance_seconds = seconds;
    EXPECT_FALSE(bad.Check(&error)) << seconds;
  }
}

TEST(SequenceSupportTest, FirstFrameKeepsItsScore) {
  SequenceSupport support{SequenceOptions()};
  std::vector<PlaceMatch> ranked = {Match("a", 10, 30), Match("a", 50, 12)};
  support.Apply(100 * kSecond, &ranked);
  EXPECT_DOUBLE_EQ(ranked[0].score, 30);
  EXPECT_EQ(ranked[0].supporting_frames, 0);
  EXPECT_DOUBLE_EQ(ranked[1].score, 12);
}

// A robot walking a stored route at the stored speed: the candidate in step with its earlier
// frames wins over a stronger one-off match elsewhere.
TEST(SequenceSupportTest, RouteInStepBeatsIsolatedMatch) {
  SequenceSupport support{SequenceOptions()};
  for (int k = 0; k < 3; ++k) {
    // Query frames at 100, 101, 102 s matched stored places at 10, 11, 12 s.
    std::vector<PlaceMatch> ranked = {Match("a", 10 + k, 15)};
    support.Apply((100 + k) * kSecond, &ranked);
    support.Record((100 + k) * kSecond, ranked);
  }
  // At 103 s: the route predicts 13 s (score 14); a wrong place at 60 s scores 20 alone.
  std::vector<PlaceMatch> ranked = {Match("a", 60, 20), Match("a", 13, 14)};
  support.Apply(103 * kSecond, &ranked);
  EXPECT_EQ(ranked[0].place.utime, 13 * kSecond);
  EXPECT_DOUBLE_EQ(ranked[0].score, (14 + 15 + 15 + 15) / 4.0);
  EXPECT_EQ(ranked[0].supporting_frames, 3);
  EXPECT_DOUBLE_EQ(ranked[0].frame_score, 14);
  EXPECT_DOUBLE_EQ(ranked[1].score, 20 / 4.0);
  EXPECT_EQ(ranked[1].supporting_frames, 0);
}

// Localization among neighbours: of two places one second apart with the same single score,
// the one in step with the earlier frames answers.
TEST(SequenceSupportTest, ChoosesTheNeighbourInStep) {
  SequenceSupport support{SequenceOptions()};
  std::vector<PlaceMatch> first = {Match("a", 20, 18)};
  support.Apply(200 * kSecond, &first);
  support.Record(200 * kSecond, first);
  std::vector<PlaceMatch> ranked = {Match("a", 24, 18), Match("a", 21, 18)};
  support.Apply(201 * kSecond, &ranked);
  EXPECT_EQ(ranked[0].place.utime, 21 * kSecond);
}

// Copies of a view sent at 10 Hz count once: supporting frames are spaced in time, so the
// score is the same at any frame rate.
TEST(SequenceSupportTest, FastCameraCountsOneViewOnce) {
  SequenceSupport slow{SequenceOptions()};
  SequenceSupport fast{SequenceOptions()};
  for (int k = 0; k < 3; ++k) {
    std::vector<PlaceMatch> a = {Match("a", 10 + k, 15)};
    slow.Apply((100 + k) * kSecond, &a);
    slow.Record((100 + k) * kSecond, a);
    for (int copy = 0; copy < 10; ++copy) {
      const int64_t t = (100 + k) * kSecond + copy * kSecond / 10;
      std::vector<PlaceMatch> b = {Match("a", 10 + k, 15)};
      fast.Apply(t, &b);
      fast.Record(t, b);
    }
  }
  std::vector<PlaceMatch> a = {Match("a", 13, 30)};
  std::vector<PlaceMatch> b = a;
  slow.Apply(103 * kSecond, &a);
  fast.Apply(103 * kSecond, &b);
  EXPECT_DOUBLE_EQ(a[0].score, (30 + 45) / 4.0);
  EXPECT_DOUBLE_EQ(b[0].score, a[0].score);
}

TEST(SequenceSupportTest, OldFramesAndOtherRobotsDoNotSupport) {
  SequenceOptions options;
  options.max_age_seconds = 5;
  SequenceSupport support(options);
  std::vector<PlaceMatch> early = {Match("a", 10, 15)};
  support.Apply(100 * kSecond, &early);
  support.Record(100 * kSecond, early);
  // 20 s later: the earlier frame is too old to count at all.
  std::vector<PlaceMatch> late = {Match("a", 30, 12)};
  support.Apply(120 * kSecond, &late);
  EXPECT_DOUBLE_EQ(late[0].score, 12);
  support.Record(120 * kSecond, late);
  // The next second: robot b's place at the predicted time does not support robot a's route.
  std::vector<PlaceMatch> other = {Match("b", 31, 12)};
  support.Apply(121 * kSecond, &other);
  EXPECT_EQ(other[0].supporting_frames, 0);
  EXPECT_DOUBLE_EQ(other[0].score, 6);
}

TEST(SequenceSupportTest, ZeroFramesJudgesEachFrameAlone) {
  SequenceOptions options;
  options.frames = 0;
  SequenceSupport support(options);
  std::vector<PlaceMatch> first = {Match("a", 10, 15)};
  support.Apply(100 * kSecond, &first);
  support.Record(100 * kSecond, first);
  std::vector<PlaceMatch> ranked = {Match("a", 60, 20), Match("a", 11, 14)};
  support.Apply(101 * kSecond, &ranked);
  EXPECT_EQ(ranked[0].place.utime, 60 * kSecond);
  EXPECT_DOUBLE_EQ(ranked[0].score, 20);
}

}  // namespace
}  // namespace placerec
