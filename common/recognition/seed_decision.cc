#include "common/recognition/seed_decision.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

namespace placerec {

bool SeedLoopOptions::Check(std::string* error) const {
  if (!(min_matched_fraction > 0.0 && min_matched_fraction <= 1.0)) {
    *error = "seed min_matched_fraction must be in (0, 1]";
    return false;
  }
  if (!(min_count_ratio >= 0.0 && min_count_ratio <= 1.0)) {
    *error = "seed min_count_ratio must be in [0, 1]";
    return false;
  }
  return true;
}

namespace {

bool CountsClose(int a, int b, double min_ratio) {
  if (a <= 0 || b <= 0) return false;
  return static_cast<double>(std::min(a, b)) >= min_ratio * static_cast<double>(std::max(a, b));
}

}  // namespace

bool SeedLoopClosure(int matched, int query_landmarks, int place_landmarks,
                     const SeedLoopOptions& options) {
  return matched > 0 && CountsClose(query_landmarks, place_landmarks, options.min_count_ratio) &&
         static_cast<double>(matched) >= options.min_matched_fraction * query_landmarks;
}

std::vector<PlaceMatch> SeedRankPlaces(
    const std::vector<LandmarkMatch>& objects, int query_landmarks,
    const std::function<std::vector<PlaceId>(LandmarkId)>& scenes_of,
    const std::function<const Place*(PlaceId)>& place_of,
    const std::function<bool(const Place&)>& allowed, const SeedLoopOptions& options,
    int max_matches, bool* loop) {
  // Step 5: M, and per scene m the frame's landmarks matched to objects seen at m.
  std::map<PlaceId, std::set<int>> matched_at;
  std::map<PlaceId, std::vector<std::pair<int, LandmarkId>>> pairs_at;
  for (const LandmarkMatch& match : objects) {
    for (const PlaceId scene : scenes_of(match.landmark)) {
      matched_at[scene].insert(match.query_object);
      pairs_at[scene].emplace_back(match.query_object, match.landmark);
    }
  }
  // Step 6.
  std::vector<PlaceMatch> ranked;
  for (const auto& [scene, landmarks] : matched_at) {
    const Place* place = place_of(scene);
    if (place == nullptr || !allowed(*place)) continue;
    PlaceMatch match;
    match.place = *place;
    match.matched_landmarks = static_cast<int>(landmarks.size());
    match.object_pairs = pairs_at[scene];
    const bool close =
        CountsClose(query_landmarks, PlaceLandmarkCount(*place), options.min_count_ratio);
    match.score = close ? match.matched_landmarks : 0.0;
    match.frame_score = match.score;
    ranked.push_back(std::move(match));
  }
  std::sort(ranked.begin(), ranked.end(), [](const PlaceMatch& a, const PlaceMatch& b) {
    if (a.score != b.score) return a.score > b.score;
    if (a.matched_landmarks != b.matched_landmarks)
      return a.matched_landmarks > b.matched_landmarks;
    return a.place.id < b.place.id;
  });
  if (static_cast<int>(ranked.size()) > max_matches) ranked.resize(max_matches);
  if (loop != nullptr) {
    *loop = !ranked.empty() && SeedLoopClosure(ranked.front().matched_landmarks, query_landmarks,
                                               PlaceLandmarkCount(ranked.front().place), options);
  }
  return ranked;
}

}  // namespace placerec
