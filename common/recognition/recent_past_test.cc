#include "common/recognition/recent_past.h"

#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "common/features/features.h"

namespace placerec {
namespace {

constexpr int64_t kSecond = 1000000;

// A strip of random keypoints along a route: a frame at position x sees the features
// [x, x + kVisible), each with a little descriptor noise, so two frames share features in
// proportion to how close they were taken.
class Route {
 public:
  static constexpr int kVisible = 300;

  explicit Route(int length, unsigned seed) : rng_(seed) {
    std::uniform_int_distribution<int> byte(0, 255);
    std::uniform_real_distribution<float> angle(0.0f, 360.0f);
    features_.create(length, kDescriptorSize, CV_8U);
    for (int r = 0; r < length; ++r) {
      for (int c = 0; c < kDescriptorSize; ++c) features_.at<uint8_t>(r, c) = byte(rng_);
      angles_.push_back(angle(rng_));
    }
  }

  // The frame at position x (`keypoints` of them at most).
  void Frame(int x, std::vector<cv::KeyPoint>* keypoints, cv::Mat* descriptors,
             int count = kVisible) {
    std::uniform_int_distribution<int> noise(-6, 6);
    std::uniform_real_distribution<float> response(0.01f, 0.1f);
    keypoints->clear();
    const int n = std::min(count, features_.rows - x);
    descriptors->create(n, kDescriptorSize, CV_8U);
    for (int i = 0; i < n; ++i) {
      for (int c = 0; c < kDescriptorSize; ++c) {
        descriptors->at<uint8_t>(i, c) =
            cv::saturate_cast<uint8_t>(features_.at<uint8_t>(x + i, c) + noise(rng_));
      }
      cv::KeyPoint k(cv::Point2f(static_cast<float>(i), 0.0f), 4.0f, angles_[x + i] + 3.0f,
                     response(rng_));
      keypoints->push_back(k);
    }
  }

 private:
  std::mt19937 rng_;
  cv::Mat features_;
  std::vector<float> angles_;
};

TEST(RecentPastTest, DefaultsPassAndBadValuesFail) {
  std::string error;
  EXPECT_TRUE(RecentPastOptions().Check(&error)) << error;
  RecentPastOptions bad;
  bad.max_views = 1;
  EXPECT_FALSE(bad.Check(&error));
  bad = RecentPastOptions();
  bad.min_gap_seconds = -1;
  EXPECT_FALSE(bad.Check(&error));
  // Taken in microseconds: 1e13 s ("never my own places") overflowed to "every own place",
  // and NaN passed.
  for (const double seconds :
       {1e13, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    bad = RecentPastOptions();
    bad.min_gap_seconds = seconds;
    EXPECT_FALSE(bad.Check(&error)) << seconds;
    bad = RecentPastOptions();
    bad.away_seconds = seconds;
    EXPECT_FALSE(bad.Check(&error)) << seconds;
  }
}

TEST(RecentPastTest, MatchesCountOnlyConsistentlyTurnedFeatures) {
  Route route(600, 1);
  std::vector<cv::KeyPoint> a_keys, b_keys, c_keys;
  cv::Mat a, b, c;
  route.Frame(0, &a_keys, &a);
  route.Frame(0, &b_keys, &b);
  route.Frame(300, &c_keys, &c);
  auto angles = [](const std::vector<cv::KeyPoint>& keys) {
    std::vector<float> out;
    for (const cv::KeyPoint& k : keys) out.push_back(k.angle);
    return out;
  };
  EXPECT_GT(ConsistentMatches(a, angles(a_keys), b, angles(b_keys)), 250);
  EXPECT_LT(ConsistentMatches(a, angles(a_keys), c, angles(c_keys)), 5);
  // The same features, each turned by a random angle: no consistent change.
  std::vector<float> random_angles;
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> angle(0.0f, 360.0f);
  for (size_t i = 0; i < b_keys.size(); ++i) random_angles.push_back(angle(rng));
  EXPECT_LT(ConsistentMatches(a, angles(a_keys), b, random_angles), 60);
}

TEST(RecentPastTest, OtherRobotsAlwaysCountOwnPlacesNeedTheGap) {
  RecentPastFilter filter;
  filter.robot = "a";
  filter.utime = 100 * kSecond;
  filter.min_gap_us = 20 * kSecond;
  filter.first_recent_sequence = 50;
  EXPECT_TRUE(filter.Allows("b", 99, 99 * kSecond));   // another robot, a moment ago
  EXPECT_TRUE(filter.Allows("a", 10, 70 * kSecond));   // own, old, before the recent views
  EXPECT_FALSE(filter.Allows("a", 10, 90 * kSecond));  // own, too young
  EXPECT_FALSE(filter.Allows("a", 50, 0));             // own, in a view still in sight
}

// A robot standing still for a minute at 30 frames per second never leaves its first view:
// every place of it stays its recent past, although each is older than the time gap.
TEST(RecentPastTest, StandingStillNeverLeavesTheView) {
  Route route(1000, 3);
  RecentPast recent{RecentPastOptions()};
  EXPECT_EQ(recent.first_recent_sequence(), INT64_MAX);
  std::vector<cv::KeyPoint> keys;
  cv::Mat descriptors;
  for (int f = 0; f < 1800; ++f) {
    route.Frame(100, &keys, &descriptors);
    recent.Observe(f, f * kSecond / 30, keys, descriptors);
  }
  EXPECT_EQ(recent.first_recent_sequence(), 0);
  EXPECT_EQ(recent.num_views(), 1);
  const RecentPastFilter filter = recent.Filter("a", 1800 * kSecond / 30);
  EXPECT_FALSE(filter.Allows("a", 0, 0));
}

// A robot driving along leaves its views behind; its early places count once they are older
// than the gap, and never while the robot still sees them.
TEST(RecentPastTest, DrivingAwayLeavesViewsBehind) {
  Route route(20000, 4);
  RecentPastOptions options;
  options.min_gap_seconds = 0;  // the motion alone
  RecentPast recent(options);
  std::vector<cv::KeyPoint> keys;
  cv::Mat descriptors;
  // 10 frames per second, 6 features per frame: a view is out of sight after 5 seconds.
  int64_t sequence = 0;
  for (int f = 0; f < 600; ++f, ++sequence) {
    route.Frame(f * 6, &keys, &descriptors);
    const RecentPastUpdate update = recent.Observe(sequence, f * kSecond / 10, keys, descriptors);
    EXPECT_TRUE(update.informative);
    const RecentPastFilter filter = recent.Filter("a", f * kSecond / 10);
    // A frame that shares features with the current one is never allowed.
    for (int back = 1; back <= 50 && back <= f; ++back) {
      EXPECT_FALSE(filter.Allows("a", sequence - back, (f - back) * kSecond / 10))
          << "frame " << f << " would close a loop " << back << " frames back";
    }
  }
  // After 60 s the first frames are far behind and old enough.
  const RecentPastFilter filter = recent.Filter("a", 600 * kSecond / 10);
  EXPECT_TRUE(filter.Allows("a", 0, 0));
  EXPECT_LT(recent.first_recent_sequence(), 600 - 50);
  EXPECT_GT(recent.first_recent_sequence(), 300);
  EXPECT_LE(recent.num_views(), options.max_views);
}

// Dark or blank frames cannot tell whether the robot moved: a robot that stands still in the
// dark for a while keeps its view.
TEST(RecentPastTest, UninformativeFramesDoNotLeaveTheView) {
  Route route(1000, 5);
  RecentPast recent{RecentPastOptions()};
  std::vector<cv::KeyPoint> keys;
  cv::Mat descriptors;
  route.Frame(0, &keys, &descriptors);
  recent.Observe(0, 0, keys, descriptors);
  route.Frame(0, &keys, &descriptors, 10);
  for (int f = 1; f < 100; ++f) {
    EXPECT_FALSE(recent.Observe(f, f * kSecond, keys, descriptors).informative);
  }
  EXPECT_EQ(recent.first_recent_sequence(), 0);
  route.Frame(0, &keys, &descriptors);
  const RecentPastUpdate update = recent.Observe(100, 100 * kSecond, keys, descriptors);
  EXPECT_EQ(update.views_seen, 1);
  EXPECT_EQ(update.views_left, 0);
  EXPECT_EQ(recent.first_recent_sequence(), 0);
}

// A robot that looks at something else for longer than away_seconds (a turn of the head) has
// been away from its first view: once that place is older than the time gap, it counts; the
// places since it came back do not.
TEST(RecentPastTest, AViewLeftAndSeenAgainCountsAfterTheTimeGap) {
  Route route(3000, 6);
  RecentPast recent{RecentPastOptions()};
  std::vector<cv::KeyPoint> keys;
  cv::Mat descriptors;
  route.Frame(0, &keys, &descriptors);
  recent.Observe(0, 0, keys, descriptors);
  route.Frame(2000, &keys, &descriptors);
  for (int f = 1; f <= 8; ++f) recent.Observe(f, f * kSecond, keys, descriptors);
  route.Frame(0, &keys, &descriptors);
  for (int f = 9; f <= 21; ++f) {
    recent.Observe(f, f * kSecond, keys, descriptors);
    const RecentPastFilter filter = recent.Filter("a", f * kSecond);
    EXPECT_EQ(filter.Allows("a", 0, 0), f >= 20) << "at " << f << " s";
    EXPECT_FALSE(filter.Allows("a", 9, 9 * kSecond));
  }
}

}  // namespace
}  // namespace placerec
