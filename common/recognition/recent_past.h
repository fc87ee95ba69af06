// A robot's own recent past (seed §5.7 step 6: a loop closure needs "a big difference between
// t_c and t_m"): which of a robot's own places are still the view it is in, and so never a loop
// closure, decided in time and motion rather than in frame counts, so that one default holds for
// a camera at 1 or at 30 frames per second and for a robot that stands still.
//
// The robot's inserted frames are summarised as a chain of views (keyframes): a frame that shares
// too little with the newest view begins a new one. Every frame is compared with the views still
// in sight; a view that no frame has seen for `away_seconds` (capture time) is left behind for
// good. The robot's places from the oldest view still in sight onwards (and, conservatively, from
// the view before it) are its recent past; so is every place younger than `min_gap_seconds`.
// A robot that stands still keeps seeing its view and never leaves it; a robot that drives away
// leaves its views one after the other, and its earlier places count as soon as it returns.
#pragma once

#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace placerec {

struct RecentPastOptions {
  // A robot's own places are its recent past for at least this many seconds of capture time
  // (utime), whatever it saw in between (seed §5.7 step 6, "a big difference between t_c and
  // t_m"; the seed counts frames instead, which depends on the frame rate).
  double min_gap_seconds = 20.0;
  // A view is left once the robot's frames have not seen it for this many seconds.
  double away_seconds = 5.0;
  // Strongest keypoints (largest DoG response) of a frame compared with the views, and kept per
  // view.
  int descriptors_per_frame = 300;
  // A frame sees a view when at least this many of its descriptors pass Lowe's ratio test
  // (ratio 0.8) against the view's and agree in orientation change (within 20 degrees of the
  // most common change). Unrelated frames reach a few such matches by chance.
  int min_matches_seen = 12;
  // A frame whose matches into the newest view are fewer than this fraction of its compared
  // descriptors begins a new view.
  double new_view_fraction = 0.25;
  // A frame with fewer keypoints than this (a dark or blank frame) cannot tell whether the robot
  // moved: it neither sees nor misses any view.
  int min_informative_keypoints = 30;
  // Views kept at most; beyond it the second oldest is dropped (the recent past only grows).
  int max_views = 16;
  // A frame that shares at least this fraction of its compared descriptors with the robot's
  // last distinct frame shows nothing new (the robot stands still, or the camera is fast): it
  // is answered but neither stored nor remembered for landmark selection, so that a fast camera
  // neither fills the map with copies of one place nor makes every object "widely visible".
  // 1 keeps every frame.
  double duplicate_fraction = 0.9;
  // A robot's tracker begins afresh when the server restarts (or forgets the robot's run). When
  // the robot's last stored place was captured at most this many seconds before its next
  // inserted frame, that place and those captured up to away_seconds before it are its views
  // again, as if the tracker had kept them, so that a robot that stood still meanwhile is not
  // answered with its own place; a robot silent for longer begins a new session, in which its
  // older places may answer it.
  double resume_within_seconds = 600.0;

  bool Check(std::string* error) const;
};

// What a lookup needs to skip a robot's recent past: a copy, safe to use while the robot's
// tracker moves on.
struct RecentPastFilter {
  std::string robot;                          // the querying robot
  int64_t utime = 0;                          // the frame's capture time, microseconds
  int64_t min_gap_us = 0;                     // places younger than this are recent
  int64_t first_recent_sequence = INT64_MAX;  // own places from this sequence on are recent

  // Whether `place_robot`'s place (`sequence`, captured at `place_utime`) may answer the frame:
  // other robots' places always may (the map is shared).
  bool Allows(const std::string& place_robot, int64_t sequence, int64_t place_utime) const;
};

// Summary of one observed frame (for logs and tests).
struct RecentPastUpdate {
  bool informative = false;  // enough keypoints to judge
  bool new_view = false;     // the frame began a view
  int views_seen = 0;        // views the frame saw
  int views_left = 0;        // views left behind by this frame
  // Share of the frame's compared descriptors matched in the robot's last distinct frame (0 when
  // there is none or the frame has no keypoints).
  double last_distinct_overlap = 0;
  bool duplicate = false;  // last_distinct_overlap >= duplicate_fraction: nothing new
};

// One of a robot's stored places as a view (RecentPast::Resume).
struct StoredView {
  int64_t sequence = 0;
  int64_t utime = 0;          // its capture time
  cv::Mat descriptors;        // CV_8U x 128, some of its stored landmarks' descriptors
  std::vector<float> angles;  // their keypoint orientations, degrees
};

// One robot's views. Not thread-safe: a robot's frames arrive one at a time.
class RecentPast {
 public:
  explicit RecentPast(const RecentPastOptions& options);

  // Takes the robot's stored places (oldest first, before any Observe) as its views, each last
  // seen at its capture time; the next frames see them or leave them as any view. At most
  // max_views of the newest are kept.
  void Resume(const std::vector<StoredView>& stored);

  // Observes an inserted frame with `sequence` captured at `utime` (its SIFT keypoints and
  // descriptors, CV_8U x 128). Sequences increase.
  RecentPastUpdate Observe(int64_t sequence, int64_t utime,
                           const std::vector<cv::KeyPoint>& keypoints, const cv::Mat& descriptors);

  // The filter for a frame of this robot captured at `utime`.
  RecentPastFilter Filter(const std::string& robot, int64_t utime) const;

  // Own places from this sequence on are the recent past (INT64_MAX before any frame).
  int64_t first_recent_sequence() const;
  int num_views() const { return static_cast<int>(views_.size()); }

 private:
  struct View {
    int64_t sequence = 0;         // the frame that began the view
    int64_t last_seen_utime = 0;  // capture time of the last frame that saw it
    bool left = false;
    cv::Mat descriptors;        // strongest descriptors of the first frame
    std::vector<float> angles;  // their keypoint orientations, degrees
  };

  RecentPastOptions options_;
  std::deque<View> views_;  // oldest first
  View last_distinct_;      // the last frame that was not a duplicate
  bool have_last_distinct_ = false;
};

// How many of `query`'s descriptors (keypoint orientations `query_angles`, degrees) match
// `train`'s by Lowe's ratio test (0.8) and turn within 20 degrees of the most common
// orientation change.
int ConsistentMatches(const cv::Mat& query, const std::vector<float>& query_angles,
                      const cv::Mat& train, const std::vector<float>& train_angles);

}  // namespace placerec
