// Sequence consistency (an addition to the seed, after SeqSLAM, Milford and Wyeth 2012, made
// causal): a revisit is a run of frames that match one stored route in step, not one frame.
// Each candidate place of a robot's frame is supported by the robot's earlier frames that
// matched the same route where it predicts: a place of the same robot taken as much earlier
// than the candidate as the earlier frame was taken before this one (a robot going the same
// way at about the same speed). A candidate's score becomes the mean over this frame and its
// supporting frames of their single-frame scores, so that it keeps the unit of one frame's
// geometric inliers and one loop threshold serves a single query and a sequence alike. A frame
// with no earlier frames (a one-off query) keeps its own score. A route walked back the other
// way gets no support (its frames count alone, diluted by the mean); why both directions are
// not allowed: docs/experiments/2026-12-02-one-default.md.
#pragma once

#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include "common/recognition/loop_decision.h"

namespace placerec {

struct SequenceOptions {
  // Earlier frames that may support a candidate (0: every frame is judged alone).
  int frames = 3;
  // Supporting frames are taken at least this many seconds apart (and from this frame), so
  // that a faster camera does not count one view several times.
  double min_spacing_seconds = 0.9;
  // Earlier frames older than this many seconds do not count (the robot stopped, or sent
  // nothing for a while).
  double max_age_seconds = 15.0;
  // A supporting frame's place must lie within this many seconds of where the candidate's
  // route predicts it.
  double tolerance_seconds = 1.5;
  // Places per frame remembered for supporting later frames (best first).
  int places_kept = 20;

  bool Check(std::string* error) const;
};

// One robot's recent single-frame answers. Not thread-safe (a robot's frames arrive in order).
class SequenceSupport {
 public:
  explicit SequenceSupport(const SequenceOptions& options) : options_(options) {}

  // Rescores `ranked` (this frame's places, best first, `score` the single-frame score) for a
  // frame taken at `utime`: sets each match's frame_score and supporting_frames, replaces its
  // score by the sequence score, and sorts best first (ties keep their order).
  void Apply(int64_t utime, std::vector<PlaceMatch>* ranked) const;

  struct Candidate {
    std::string robot;
    int64_t utime = 0;
    double score = 0;
  };
  // What is remembered of one frame: the single-frame scores (frame_score) of its best places.
  struct Frame {
    int64_t utime = 0;
    std::vector<Candidate> places;
  };

  // The frame at `utime` with places `ranked` as Record would remember it; changes nothing, so
  // that a frame is remembered only once it is stored.
  Frame Summarise(int64_t utime, const std::vector<PlaceMatch>& ranked) const;
  void Record(Frame frame);
  void Record(int64_t utime, const std::vector<PlaceMatch>& ranked) {
    Record(Summarise(utime, ranked));
  }

  const SequenceOptions& options() const { return options_; }

 private:
  // The earlier frames that may support a frame at `utime`, newest first.
  std::vector<const Frame*> Supporters(int64_t utime) const;

  SequenceOptions options_;
  std::deque<Frame> history_;  // oldest first
};

}  // namespace placerec
