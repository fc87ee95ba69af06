#include "common/recognition/recent_past.h"

#include <algorithm>
#include <numeric>
#include <string>

#include "common/features/features.h"
#include "common/recognition/descriptor_matching.h"
#include "common/recognition/types.h"
#include "common/util/logging.h"

namespace placerec {
namespace {

// Lowe's ratio and the orientation tolerance of a frame-to-view comparison.
constexpr double kRatio = 0.8;
constexpr double kOrientationTolerance = 20.0;

}  // namespace

bool RecentPastOptions::Check(std::string* error) const {
  if (!(min_gap_seconds >= 0 && min_gap_seconds <= kMaxWindowSeconds) ||
      !(away_seconds >= 0 && away_seconds <= kMaxWindowSeconds)) {
    *error = "recent past min_gap_seconds and away_seconds must be in [0, " +
             std::to_string(static_cast<int>(kMaxWindowSeconds)) + "] (a day)";
    return false;
  }
  if (descriptors_per_frame < 1 || min_matches_seen < 1) {
    *error = "recent past descriptors_per_frame and min_matches_seen must be >= 1";
    return false;
  }
  if (new_view_fraction < 0 || new_view_fraction > 1) {
    *error = "recent past new_view_fraction must be in [0, 1]";
    return false;
  }
  if (!(resume_within_seconds >= 0 && resume_within_seconds <= kMaxWindowSeconds)) {
    *error = "recent past resume_within_seconds must be in [0, " +
             std::to_string(static_cast<int>(kMaxWindowSeconds)) + "] (a day)";
    return false;
  }
  if (duplicate_fraction <= 0 || duplicate_fraction > 1) {
    *error = "recent past duplicate_fraction must be in (0, 1]";
    return false;
  }
  if (min_informative_keypoints < 0 || max_views < 2) {
    *error = "recent past min_informative_keypoints must be >= 0 and max_views >= 2";
    return false;
  }
  return true;
}

bool RecentPastFilter::Allows(const std::string& place_robot, int64_t sequence,
                              int64_t place_utime) const {
  if (place_robot != robot) return true;
  if (sequence >= first_recent_sequence) return false;
  return utime - place_utime >= min_gap_us;
}

int ConsistentMatches(const cv::Mat& query, const std::vector<float>& query_angles,
                      const cv::Mat& train, const std::vector<float>& train_angles) {
  const std::vector<DescriptorMatch> matches = MatchRatioTest(query, train, kRatio);
  std::vector<double> changes;
  changes.reserve(matches.size());
  for (const DescriptorMatch& m : matches) {
    changes.push_back(AngleDifference(query_angles[m.query], train_angles[m.train]));
  }
  const std::vector<bool> consistent = ConsistentOrientation(changes, kOrientationTolerance);
  return static_cast<int>(std::count(consistent.begin(), consistent.end(), true));
}

RecentPast::RecentPast(const RecentPastOptions& options) : options_(options) {}

void RecentPast::Resume(const std::vector<StoredView>& stored) {
  const size_t first = stored.size() > static_cast<size_t>(options_.max_views)
                           ? stored.size() - options_.max_views
                           : 0;
  for (size_t i = first; i < stored.size(); ++i) {
    const StoredView& place = stored[i];
    CHECK_EQ(place.descriptors.rows, static_cast<int>(place.angles.size()));
    View view;
    view.sequence = place.sequence;
    view.last_seen_utime = place.utime;
    view.descriptors = place.descriptors;
    view.angles = place.angles;
    views_.push_back(std::move(view));
  }
}

RecentPastUpdate RecentPast::Observe(int64_t sequence, int64_t utime,
                                     const std::vector<cv::KeyPoint>& keypoints,
                                     const cv::Mat& descriptors) {
  CHECK_EQ(static_cast<int>(keypoints.size()), descriptors.rows);
  RecentPastUpdate update;

  // The frame's strongest keypoints (ties by position in the list, so the choice is stable).
  std::vector<int> order(keypoints.size());
  std::iota(order.begin(), order.end(), 0);
  const size_t kept = std::min<size_t>(order.size(), options_.descriptors_per_frame);
  std::partial_sort(order.begin(), order.begin() + kept, order.end(), [&](int a, int b) {
    if (keypoints[a].response != keypoints[b].response) {
      return keypoints[a].response > keypoints[b].response;
    }
    return a < b;
  });
  View frame;
  frame.sequence = sequence;
  frame.last_seen_utime = utime;
  frame.descriptors.create(static_cast<int>(kept), kDescriptorSize, CV_8U);
  for (size_t i = 0; i < kept; ++i) {
    descriptors.row(order[i]).copyTo(frame.descriptors.row(static_cast<int>(i)));
    frame.angles.push_back(keypoints[order[i]].angle);
  }

  if (kept > 0 && !last_distinct_.descriptors.empty()) {
    update.last_distinct_overlap =
        static_cast<double>(ConsistentMatches(frame.descriptors, frame.angles,
                                              last_distinct_.descriptors, last_distinct_.angles)) /
        static_cast<double>(kept);
    update.duplicate = update.last_distinct_overlap >= options_.duplicate_fraction;
  } else if (kept == 0) {
    // A blank frame after a blank frame shows nothing new either.
    update.duplicate = have_last_distinct_ && last_distinct_.descriptors.empty();
  }
  if (!update.duplicate) {
    last_distinct_ = frame;
    have_last_distinct_ = true;
  }
  if (static_cast<int>(keypoints.size()) < options_.min_informative_keypoints) return update;
  update.informative = true;

  // Which views the frame still sees; those unseen for long enough are left behind.
  const int64_t away_us = static_cast<int64_t>(options_.away_seconds * 1e6);
  int newest_matches = 0;
  for (View& view : views_) {
    if (view.left) continue;
    const int matches =
        ConsistentMatches(frame.descriptors, frame.angles, view.descriptors, view.angles);
    if (&view == &views_.back()) newest_matches = matches;
    if (matches >= options_.min_matches_seen) {
      view.last_seen_utime = std::max(view.last_seen_utime, utime);
      ++update.views_seen;
    } else if (utime - view.last_seen_utime >= away_us) {
      view.left = true;
      ++update.views_left;
    }
  }
  if (views_.empty() || views_.back().left ||
      newest_matches < options_.new_view_fraction * static_cast<double>(kept)) {
    views_.push_back(std::move(frame));
    update.new_view = true;
  }
  // The oldest view stays while the next one is still in sight: the places between two views
  // are only behind the robot once it has left the later one too.
  while (views_.size() >= 2 && views_[0].left && views_[1].left) views_.pop_front();
  while (static_cast<int>(views_.size()) > options_.max_views) views_.erase(views_.begin() + 1);
  return update;
}

int64_t RecentPast::first_recent_sequence() const {
  return views_.empty() ? INT64_MAX : views_.front().sequence;
}

RecentPastFilter RecentPast::Filter(const std::string& robot, int64_t utime) const {
  RecentPastFilter filter;
  filter.robot = robot;
  filter.utime = utime;
  filter.min_gap_us = static_cast<int64_t>(options_.min_gap_seconds * 1e6);
  filter.first_recent_sequence = first_recent_sequence();
  return filter;
}

}  // namespace placerec
