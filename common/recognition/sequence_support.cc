#include "common/recognition/sequence_support.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "common/recognition/types.h"

namespace placerec {

bool SequenceOptions::Check(std::string* error) const {
  if (frames < 0 || frames > 32) {
    *error = "sequence frames must be in [0, 32] (0: every frame alone)";
    return false;
  }
  const std::string day = std::to_string(static_cast<int>(kMaxWindowSeconds));
  if (!(min_spacing_seconds >= 0 && min_spacing_seconds <= kMaxWindowSeconds) ||
      !(max_age_seconds > 0 && max_age_seconds <= kMaxWindowSeconds)) {
    *error = "sequence min_spacing_seconds must be in [0, " + day +
             "] and max_age_seconds in (0, " + day + "] (a day)";
    return false;
  }
  if (!(tolerance_seconds > 0 && tolerance_seconds <= kMaxWindowSeconds)) {
    *error = "sequence tolerance_seconds must be in (0, " + day + "] (a day)";
    return false;
  }
  if (places_kept < 1) {
    *error = "sequence places_kept must be at least 1";
    return false;
  }
  return true;
}

std::vector<const SequenceSupport::Frame*> SequenceSupport::Supporters(int64_t utime) const {
  std::vector<const Frame*> chosen;
  const auto spacing_us = static_cast<int64_t>(std::llround(options_.min_spacing_seconds * 1e6));
  const auto max_age_us = static_cast<int64_t>(std::llround(options_.max_age_seconds * 1e6));
  int64_t last = utime;
  for (auto it = history_.rbegin();
       it != history_.rend() && static_cast<int>(chosen.size()) < options_.frames; ++it) {
    if (utime - it->utime > max_age_us) break;
    if (last - it->utime < spacing_us) continue;
    chosen.push_back(&*it);
    last = it->utime;
  }
  return chosen;
}

void SequenceSupport::Apply(int64_t utime, std::vector<PlaceMatch>* ranked) const {
  const std::vector<const Frame*> supporters =
      options_.frames > 0 ? Supporters(utime) : std::vector<const Frame*>();
  const auto tolerance_us = static_cast<int64_t>(std::llround(options_.tolerance_seconds * 1e6));
  for (PlaceMatch& match : *ranked) {
    double sum = match.frame_score;
    match.supporting_frames = 0;
    for (const Frame* frame : supporters) {
      // Where the route predicts the supporting frame's place: as much earlier as that frame.
      const int64_t predicted = match.place.utime - (utime - frame->utime);
      double best = 0;
      for (const Candidate& c : frame->places) {
        if (c.robot == match.place.robot && std::llabs(c.utime - predicted) <= tolerance_us) {
          best = std::max(best, c.score);
        }
      }
      sum += best;
      if (best > 0) ++match.supporting_frames;
    }
    match.score = sum / static_cast<double>(1 + supporters.size());
  }
  std::stable_sort(ranked->begin(), ranked->end(),
                   [](const PlaceMatch& a, const PlaceMatch& b) { return a.score > b.score; });
}

SequenceSupport::Frame SequenceSupport::Summarise(int64_t utime,
                                                  const std::vector<PlaceMatch>& ranked) const {
  Frame frame;
  frame.utime = utime;
  for (const PlaceMatch& match : ranked) {
    if (static_cast<int>(frame.places.size()) >= options_.places_kept) break;
    if (match.frame_score <= 0) continue;
    frame.places.push_back({match.place.robot, match.place.utime, match.frame_score});
  }
  return frame;
}

void SequenceSupport::Record(Frame frame) {
  if (options_.frames <= 0) return;
  const int64_t utime = frame.utime;
  history_.push_back(std::move(frame));
  // Keep what Supporters can still reach: frames within max_age of the newest.
  const auto max_age_us = static_cast<int64_t>(std::llround(options_.max_age_seconds * 1e6));
  while (!history_.empty() && utime - history_.front().utime > max_age_us) history_.pop_front();
}

}  // namespace placerec
