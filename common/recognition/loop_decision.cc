#include "common/recognition/loop_decision.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include <opencv2/calib3d.hpp>

#include "common/recognition/descriptor_matching.h"
#include "common/util/logging.h"

namespace placerec {

bool LoopDecisionOptions::Check(std::string* error) const {
  if (orientation_tolerance < 0 || orientation_tolerance > 180) {
    *error = "loop orientation_tolerance must be in [0, 180] degrees";
    return false;
  }
  if (ransac_threshold <= 0) {
    *error = "loop ransac_threshold must be positive (pixels)";
    return false;
  }
  if (ransac_confidence <= 0 || ransac_confidence >= 1) {
    *error = "loop ransac_confidence must be in (0, 1)";
    return false;
  }
  if (max_inliers_per_landmark < 0) {
    *error = "loop max_inliers_per_landmark must be >= 0 (0: no cap)";
    return false;
  }
  if (ransac_iterations < 1 || min_verification_points < 0) {
    *error = "loop ransac_iterations must be >= 1 and min_verification_points >= 0";
    return false;
  }
  if (max_verified_places < 1 || max_matches < 1) {
    *error = "loop max_verified_places and max_matches must be at least 1";
    return false;
  }
  if (!(localization_window_seconds >= 0 && localization_window_seconds <= kMaxWindowSeconds)) {
    *error = "loop localization_window_seconds must be in [0, " +
             std::to_string(static_cast<int>(kMaxWindowSeconds)) + "] (a day)";
    return false;
  }
  if (!(localization_score_fraction >= 0 && localization_score_fraction <= 1)) {
    *error = "loop localization_score_fraction must be in [0, 1]";
    return false;
  }
  if (!(noise_inliers >= 0) || !std::isfinite(noise_inliers)) {
    *error = "loop noise_inliers must be non-negative and finite";
    return false;
  }
  if (min_score < 0) {
    *error = "loop min_score must be non-negative";
    return false;
  }
  return true;
}

namespace {

struct KeypointPair {
  const cv::KeyPoint* query;
  const cv::KeyPoint* stored;
  LandmarkId landmark;
};

// Matches whose orientation change is within `tolerance` degrees of the most common change.
std::vector<KeypointPair> ConsistentPairs(const std::vector<KeypointPair>& pairs,
                                          double tolerance) {
  if (tolerance <= 0 || pairs.empty()) return pairs;
  std::vector<double> changes;
  changes.reserve(pairs.size());
  for (const KeypointPair& pair : pairs) {
    changes.push_back(AngleDifference(pair.query->angle, pair.stored->angle));
  }
  const std::vector<bool> consistent = ConsistentOrientation(changes, tolerance);
  std::vector<KeypointPair> kept;
  for (size_t i = 0; i < pairs.size(); ++i) {
    if (consistent[i]) kept.push_back(pairs[i]);
  }
  return kept;
}

// Inliers counted at most max_inliers_per_landmark times per landmark and at most
// max_inliers_per_cell times per grid cell of the query frame (no cap where a cap is 0).
double CappedScore(const PlaceMatch& match, const LoopDecisionOptions& options) {
  std::map<int64_t, int> per_landmark;
  std::map<std::pair<int, int>, int> per_cell;
  const int cell = std::max(1, options.inlier_cell_size);
  double score = 0;
  for (size_t i = 0; i < match.point_pairs.size(); ++i) {
    if (options.max_inliers_per_landmark > 0 &&
        ++per_landmark[match.point_landmarks[i].value()] > options.max_inliers_per_landmark) {
      continue;
    }
    const cv::Point2f& p = match.point_pairs[i].first;
    if (options.max_inliers_per_cell > 0 &&
        ++per_cell[{static_cast<int>(p.x) / cell, static_cast<int>(p.y) / cell}] >
            options.max_inliers_per_cell) {
      continue;
    }
    score += 1;
  }
  return score;
}

// Seconds from `b`'s capture to `a`'s (exact for whole seconds).
double SecondsApart(const Place& a, const Place& b) {
  return static_cast<double>(a.utime - b.utime) / 1e6;
}

// Whether `a` is a neighbour of `b` for localization: the same robot, within the window.
bool LocalizationNeighbour(const Place& a, const Place& b, const LoopDecisionOptions& options) {
  const int64_t window_us = std::llround(options.localization_window_seconds * 1e6);
  return a.robot == b.robot && std::abs(a.utime - b.utime) <= window_us;
}

// Which of `ranked` (best first) answers. The best place's neighbours (same robot, within the
// window) with a clear score tell how the scale of the query's features compares with theirs:
// where a weighted line through (capture time, median log scale ratio) crosses 0 is where the query
// was taken. Without a clear trend, the neighbour with the scale ratio closest to 0 answers.
size_t Localize(const std::vector<PlaceMatch>& ranked, const LoopDecisionOptions& options) {
  const PlaceMatch& best = ranked.front();
  const auto neighbour = [&](const PlaceMatch& m) {
    return LocalizationNeighbour(m.place, best.place, options);
  };
  double sw = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  int fitted = 0;
  for (const PlaceMatch& m : ranked) {
    if (!neighbour(m) || m.inliers <= 0 || m.score < options.noise_inliers) continue;
    const double x = SecondsApart(m.place, best.place);
    const double w = m.score;
    sw += w;
    sx += w * x;
    sy += w * m.log_scale;
    sxx += w * x * x;
    sxy += w * x * m.log_scale;
    ++fitted;
  }
  const double denominator = sw * sxx - sx * sx;
  if (fitted >= 3 && denominator > 1e-9) {
    const double slope = (sw * sxy - sx * sy) / denominator;
    const double intercept = (sy - slope * sx) / sw;
    if (std::abs(slope) >= options.min_scale_slope) {
      const double crossing = std::clamp(-intercept / slope, -options.localization_window_seconds,
                                         options.localization_window_seconds);
      size_t chosen = 0;
      double nearest = std::abs(crossing);
      for (size_t i = 1; i < ranked.size(); ++i) {
        if (!neighbour(ranked[i])) continue;
        const double d = std::abs(SecondsApart(ranked[i].place, best.place) - crossing);
        if (d < nearest - 1e-9) {
          nearest = d;
          chosen = i;
        }
      }
      return chosen;
    }
  }
  const double floor =
      std::max(options.noise_inliers, options.localization_score_fraction * best.score);
  size_t chosen = 0;
  for (size_t i = 1; i < ranked.size(); ++i) {
    const PlaceMatch& m = ranked[i];
    if (!neighbour(m) || m.score < floor) continue;
    if (std::abs(m.log_scale) < std::abs(ranked[chosen].log_scale)) chosen = i;
  }
  return chosen;
}

}  // namespace

std::vector<std::pair<std::string, int>> MatchedClasses(const PlaceMatch& match,
                                                        const LandmarkIndex& index) {
  std::set<int64_t> landmarks;
  for (const auto& pair : match.object_pairs) landmarks.insert(pair.second.value());
  for (const LandmarkId id : match.point_landmarks) landmarks.insert(id.value());
  std::map<std::string, int> counts;
  for (const int64_t id : landmarks) {
    const int32_t slot = index.SlotOf(LandmarkId(id));
    if (slot < 0) continue;
    const std::string& name = index.landmark(slot).object_class;
    if (!name.empty()) ++counts[name];
  }
  std::vector<std::pair<std::string, int>> classes(counts.begin(), counts.end());
  std::stable_sort(classes.begin(), classes.end(),
                   [](const auto& a, const auto& b) { return a.second > b.second; });
  return classes;
}

std::vector<PlaceMatch> RankPlaces(const IndexResult& found,
                                   const std::vector<std::vector<cv::KeyPoint>>& query_keypoints,
                                   int query_width, const LandmarkIndex& index,
                                   const std::function<const Place*(PlaceId)>& place_of,
                                   const LoopDecisionOptions& options) {
  std::map<PlaceId, PlaceMatch> by_place;
  for (const LandmarkMatch& match : found.objects) {
    const int32_t slot = index.SlotOf(match.landmark);
    CHECK_GE(slot, 0);
    PlaceMatch& place = by_place[match.place];
    place.object_pairs.emplace_back(match.query_object, match.landmark);
    place.landmark_boxes.push_back(index.landmark(slot).box);
  }
  for (const auto& [place_id, points] : found.place_points) by_place[place_id];
  std::vector<PlaceMatch> ranked;
  std::map<PlaceId, std::vector<double>> log_scales;  // per place, per point pair
  for (auto& [place_id, match] : by_place) {
    const Place* place = place_of(place_id);
    CHECK(place != nullptr) << "place " << place_id << " is in the index but not in the map";
    match.place = *place;
    std::set<int64_t> landmarks;
    for (const auto& pair : match.object_pairs) landmarks.insert(pair.second.value());
    match.matched_landmarks = static_cast<int>(landmarks.size());
    const auto points = found.place_points.find(place_id);
    if (points != found.place_points.end()) {
      std::vector<KeypointPair> pairs;
      for (const PointMatch& p : points->second) {
        const Landmark& landmark = index.landmark(p.slot);
        pairs.push_back({&query_keypoints[p.query_object][p.query_row],
                         &landmark.keypoints[p.train], landmark.id});
      }
      const double width_ratio = query_width > 0 && place->image_width > 0
                                     ? static_cast<double>(place->image_width) / query_width
                                     : 1.0;
      for (const KeypointPair& pair : ConsistentPairs(pairs, options.orientation_tolerance)) {
        match.point_pairs.emplace_back(pair.query->pt, pair.stored->pt);
        match.point_landmarks.push_back(pair.landmark);
        log_scales[place_id].push_back(std::log(std::max(1e-3f, pair.query->size) /
                                                std::max(1e-3f, pair.stored->size) * width_ratio));
      }
    }
    match.matched_descriptors = static_cast<int>(match.point_pairs.size());
    match.score = match.matched_descriptors;
    ranked.push_back(std::move(match));
  }
  auto by_score = [](const PlaceMatch& a, const PlaceMatch& b) {
    if (a.score != b.score) return a.score > b.score;
    return a.place.id < b.place.id;
  };
  std::sort(ranked.begin(), ranked.end(), by_score);

  if (options.geometric_verification) {
    const size_t min_points = static_cast<size_t>(std::max(8, options.min_verification_points));
    // Fits the fundamental matrix to a place's matches; keeps the inliers and scores them.
    auto verify = [&](PlaceMatch& match) {
      match.inliers = 0;
      std::vector<cv::Point2f> a;
      std::vector<cv::Point2f> b;
      for (const auto& [p, q] : match.point_pairs) {
        a.push_back(p);
        b.push_back(q);
      }
      std::vector<uint8_t> mask;
      const cv::Mat f =
          cv::findFundamentalMat(a, b, cv::USAC_ACCURATE, options.ransac_threshold,
                                 options.ransac_confidence, options.ransac_iterations, mask);
      std::vector<std::pair<cv::Point2f, cv::Point2f>> inliers;
      std::vector<LandmarkId> inlier_landmarks;
      std::vector<double> inlier_scales;
      if (!f.empty() && mask.size() == a.size()) {
        const std::vector<double>& scales = log_scales[match.place.id];
        for (size_t k = 0; k < mask.size(); ++k) {
          if (!mask[k]) continue;
          inliers.push_back(match.point_pairs[k]);
          inlier_landmarks.push_back(match.point_landmarks[k]);
          inlier_scales.push_back(scales[k]);
        }
      }
      if (!inlier_scales.empty()) {
        std::nth_element(inlier_scales.begin(), inlier_scales.begin() + inlier_scales.size() / 2,
                         inlier_scales.end());
        match.log_scale = inlier_scales[inlier_scales.size() / 2];
      }
      match.inliers = static_cast<int>(inliers.size());
      match.point_pairs = std::move(inliers);
      match.point_landmarks = std::move(inlier_landmarks);
      match.score = CappedScore(match, options);
    };
    auto discard = [](PlaceMatch& match) {
      match.inliers = 0;
      match.point_pairs.clear();
      match.point_landmarks.clear();
      match.score = 0;
    };
    // Places by decreasing match count; a place with fewer matches than half the best score so
    // far cannot beat it and is skipped (unless it neighbours the best, see below).
    const size_t verified = std::min<size_t>(ranked.size(), options.max_verified_places);
    double best_score = 0;
    for (size_t i = 0; i < ranked.size(); ++i) {
      PlaceMatch& match = ranked[i];
      const double points = static_cast<double>(match.point_pairs.size());
      if (i < verified && points >= min_points && points >= 0.5 * best_score) {
        verify(match);
        best_score = std::max(best_score, match.score);
      } else {
        match.inliers = -1;  // not verified yet
      }
    }
    // Localization needs the best place's neighbours verified too: at most
    // max_verified_places of them, nearest to the best in time (then in place id) first, however
    // many a stopped clock or a fast camera puts within the window.
    const auto best = std::max_element(ranked.begin(), ranked.end(), by_score);
    std::vector<std::pair<std::pair<int64_t, int64_t>, PlaceMatch*>> neighbours;
    for (PlaceMatch& match : ranked) {
      if (match.inliers >= 0) continue;
      const bool neighbour = best != ranked.end() && best->score > 0 &&
                             match.place.robot == best->place.robot &&
                             LocalizationNeighbour(match.place, best->place, options) &&
                             match.point_pairs.size() >= min_points;
      if (neighbour) {
        neighbours.push_back({{std::llabs(match.place.utime - best->place.utime),
                               std::llabs(match.place.id.value() - best->place.id.value())},
                              &match});
      } else {
        discard(match);
      }
    }
    std::sort(neighbours.begin(), neighbours.end(),
              [](const auto& a, const auto& b) { return a.first < b.first; });
    for (size_t i = 0; i < neighbours.size(); ++i) {
      if (static_cast<int>(i) < options.max_verified_places) {
        verify(*neighbours[i].second);
      } else {
        discard(*neighbours[i].second);
      }
    }
    std::sort(ranked.begin(), ranked.end(), by_score);
  }
  if (options.geometric_verification && options.localization_window_seconds > 0 &&
      ranked.size() > 1) {
    const size_t chosen = Localize(ranked, options);
    if (chosen != 0) {
      // The chosen place answers with the evidence of its neighbourhood: the best score.
      const double score = ranked.front().score;
      std::rotate(ranked.begin(), ranked.begin() + chosen, ranked.begin() + chosen + 1);
      ranked.front().score = std::max(ranked.front().score, score);
    }
  }
  if (static_cast<int>(ranked.size()) > options.max_matches) ranked.resize(options.max_matches);
  for (PlaceMatch& match : ranked) {
    match.frame_score = match.score;
    match.landmark_classes = MatchedClasses(match, index);
  }
  return ranked;
}

}  // namespace placerec
