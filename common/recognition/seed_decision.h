// The seed's own loop decision (seed §5.7 steps 5-6), for the seed's recognition mode: every
// landmark of the frame that matches a stored object (§5.6) brings that object's scene set, the
// places it was seen at; a place m of that set is a loop closure when about half of the frame's
// landmarks LO_c matched objects seen at m and the two landmark counts |LO_c| and |LO_m| are
// close. The time gap of step 6 is the recent-past rule (recent_past.h), applied to m.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "common/recognition/landmark_index.h"
#include "common/recognition/loop_decision.h"
#include "common/recognition/types.h"

namespace placerec {

struct SeedLoopOptions {
  // "around 50% of LO_c get matched with LO_m" (§5.7 step 6).
  double min_matched_fraction = 0.5;
  // "|LO_c| is close to |LO_m|": the smaller count is at least this fraction of the larger (the
  // seed gives no number; 1/2 is this implementation's reading).
  double min_count_ratio = 0.5;

  bool Check(std::string* error) const;
};

// Ranks the places of the scene sets of the matched objects, best first, at most `max_matches`.
// `objects` are the frame's object-level matches (query object = landmark index of the frame);
// `query_landmarks` is |LO_c|; `scenes_of(id)` gives a stored landmark's scene set (its own place
// and the places that saw it again); `place_of` looks a place up; `allowed` is the recent-past
// rule. A place's matched_landmarks is the number of the frame's landmarks that matched an object
// seen at it; its score is that number when the landmark counts are close and 0 otherwise.
// `loop` (may be null) receives whether the best place passes step 6.
std::vector<PlaceMatch> SeedRankPlaces(
    const std::vector<LandmarkMatch>& objects, int query_landmarks,
    const std::function<std::vector<PlaceId>(LandmarkId)>& scenes_of,
    const std::function<const Place*(PlaceId)>& place_of,
    const std::function<bool(const Place&)>& allowed, const SeedLoopOptions& options,
    int max_matches, bool* loop);

// Whether a place with `matched` of the frame's `query_landmarks` landmarks matched and
// `place_landmarks` landmarks of its own passes step 6.
bool SeedLoopClosure(int matched, int query_landmarks, int place_landmarks,
                     const SeedLoopOptions& options);

// The landmarks a place is represented by (|LO_m|): those stored with it and those it saw again.
inline int PlaceLandmarkCount(const Place& place) {
  return place.num_landmarks + static_cast<int>(place.seen_landmarks.size());
}

}  // namespace placerec
