#include "common/recognition/landmark_index.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <iterator>
#include <limits>
#include <tuple>
#include <utility>

#include "common/features/features.h"
#include "common/util/logging.h"
#include "common/util/timer.h"

namespace placerec {

bool LandmarkIndexOptions::Check(std::string* error) const {
  if (!(vote_window_seconds >= 0 && vote_window_seconds <= kMaxWindowSeconds)) {
    *error = "index vote_window_seconds must be in [0, " +
             std::to_string(static_cast<int>(kMaxWindowSeconds)) + "] (a day)";
    return false;
  }
  if (exact_places < 0 || exact_places > 1000) {
    *error = "index exact_places must be in [0, 1000]";
    return false;
  }
  if (exact_route_neighbours < 0 || exact_route_neighbours > LandmarkIndex::kMaxVoteNeighbours) {
    *error = "index exact_route_neighbours must be in [0, " +
             std::to_string(LandmarkIndex::kMaxVoteNeighbours) + "]";
    return false;
  }
  if (exact_max_comparisons < 0) {
    *error = "index exact_max_comparisons must be at least 0";
    return false;
  }
  if (count_range_low < 0 || count_range_low > 1) {
    *error = "index count_range_low must be in [0, 1]";
    return false;
  }
  if (!(count_range_high >= 1) || !std::isfinite(count_range_high)) {
    *error = "index count_range_high must be at least 1 and finite";
    return false;
  }
  return colour.Check(error) && matching.Check(error) && flann.Check(error);
}

LandmarkIndex::LandmarkIndex(const LandmarkIndexOptions& options)
    : options_(options), descriptors_(options.flann) {}

void LandmarkIndex::Add(Landmark&& landmark) {
  CHECK(landmark.id.IsValid());
  CHECK(landmark.place.IsValid());
  CHECK(place_info_.count(landmark.place) > 0) << "AddPlace(" << landmark.place << ") first";
  CHECK(landmark.descriptors.empty() ||
        (landmark.descriptors.type() == CV_8U && landmark.descriptors.cols == kDescriptorSize));
  CHECK_EQ(static_cast<int>(landmark.keypoints.size()), landmark.descriptors.rows);
  const int32_t slot = static_cast<int32_t>(landmarks_.size());
  landmarks_.push_back(std::move(landmark));
  const Landmark& stored = landmarks_.back();
  slot_of_id_[stored.id.value()] = slot;
  by_count_.Insert(stored.sift_count, slot);
  slots_of_place_[stored.place].push_back(slot);
  descriptors_.Add(slot, stored.descriptors);
  num_descriptors_ += stored.descriptors.rows;
}

void LandmarkIndex::AddPlace(const Place& place) {
  CHECK(place.id.IsValid());
  auto [it, inserted] = robot_number_.emplace(place.robot, static_cast<int>(robot_number_.size()));
  place_info_[place.id] = {it->second, place.utime};
  place_by_time_.insert({it->second, place.utime, place.id.value()});
}

bool LandmarkIndex::SameLocation(PlaceId a, PlaceId b) const {
  if (a == b) return true;
  const auto ia = place_info_.find(a);
  const auto ib = place_info_.find(b);
  if (ia == place_info_.end() || ib == place_info_.end()) return false;
  return ia->second.robot == ib->second.robot &&
         std::abs(ia->second.utime - ib->second.utime) <= VoteWindowUs();
}

std::vector<PlaceId> LandmarkIndex::VoteNeighbours(
    PlaceId place, const std::function<bool(PlaceId)>& place_allowed) const {
  const PlaceInfo& info = place_info_.at(place);
  const int64_t window = VoteWindowUs();
  // Outward from the place's own entry, one step to whichever side is nearer: in time, and among
  // places of the same time (a clock that stands still) by place id, the order of the entries.
  const auto own = place_by_time_.find({info.robot, info.utime, place.value()});
  CHECK(own != place_by_time_.end());
  auto before = own;
  auto after = std::next(own);
  const auto distance = [&](decltype(own) it) {
    return std::make_pair(std::abs(std::get<1>(*it) - info.utime),
                          std::abs(std::get<2>(*it) - place.value()));
  };
  const auto in_window = [&](decltype(own) it) {
    return std::get<0>(*it) == info.robot && std::abs(std::get<1>(*it) - info.utime) <= window;
  };
  // Places not allowed are passed over, but the walk stops after a bounded number of steps.
  std::vector<PlaceId> neighbours;
  for (int steps = 0;
       static_cast<int>(neighbours.size()) < kMaxVoteNeighbours && steps < kMaxVoteNeighbourSteps;
       ++steps) {
    const bool can_after = after != place_by_time_.end() && in_window(after);
    const bool can_before = before != place_by_time_.begin() && in_window(std::prev(before));
    if (!can_after && !can_before) break;
    const bool take_after =
        can_after && (!can_before || distance(after) <= distance(std::prev(before)));
    const PlaceId next(std::get<2>(take_after ? *after++ : *--before));
    if (place_allowed(next)) neighbours.push_back(next);
  }
  return neighbours;
}

int32_t LandmarkIndex::SlotOf(LandmarkId id) const {
  const auto it = slot_of_id_.find(id.value());
  return it == slot_of_id_.end() ? -1 : it->second;
}

std::vector<int32_t> LandmarkIndex::SlotsOfPlace(PlaceId place) const {
  const auto found = slots_of_place_.find(place);
  return found == slots_of_place_.end() ? std::vector<int32_t>() : found->second;
}

bool LandmarkIndex::CandidateByColour(const IndexQuery& object, int32_t slot) const {
  return !options_.use_colour_filter ||
         ColoursCompatible(object.colour, landmarks_[slot].colour, options_.colour);
}

std::vector<int32_t> LandmarkIndex::Candidates(const IndexQuery& object) const {
  std::vector<int32_t> slots;
  if (options_.use_count_range) {
    int lo = 0;
    int hi = 0;
    CountRange(object.sift_count, options_.count_range_low, options_.count_range_high, &lo, &hi);
    by_count_.ForEachInRange(lo, hi, [&](int, int32_t slot) {
      if (CandidateByColour(object, slot)) slots.push_back(slot);
    });
    std::sort(slots.begin(), slots.end());
  } else {
    for (int32_t slot = 0; slot < static_cast<int32_t>(landmarks_.size()); ++slot) {
      if (CandidateByColour(object, slot)) slots.push_back(slot);
    }
  }
  return slots;
}

IndexResult LandmarkIndex::Query(const std::vector<IndexQuery>& objects,
                                 const std::function<bool(PlaceId)>& place_allowed) const {
  IndexResult result;
  if (landmarks_.empty() || objects.empty()) return result;
  // Places are checked once per landmark slot, lazily.
  std::vector<int8_t> place_ok(landmarks_.size(), -1);
  auto allowed_slot = [&](int32_t slot) {
    int8_t& ok = place_ok[slot];
    if (ok < 0) ok = place_allowed(landmarks_[slot].place) ? 1 : 0;
    return ok == 1;
  };

  std::vector<cv::Mat> query_descriptors;
  query_descriptors.reserve(objects.size());
  for (const IndexQuery& object : objects) query_descriptors.push_back(object.descriptors);
  const StackedQuery query = StackedQuery::Stack(query_descriptors);

  if (options_.search == IndexSearch::kExhaustive) {
    for (size_t o = 0; o < objects.size(); ++o) {
      if (!objects[o].is_object) continue;
      const std::vector<int32_t> candidates = Candidates(objects[o]);
      result.stats.candidates += static_cast<int64_t>(candidates.size());
      for (int32_t slot : candidates) {
        if (!allowed_slot(slot)) continue;
        ++result.stats.matching.verified_pairs;
        std::vector<DescriptorMatch> matches = MatchRatioTest(
            objects[o].descriptors, landmarks_[slot].descriptors, options_.matching.ratio);
        if (static_cast<int>(matches.size()) < options_.matching.min_matches) continue;
        const Landmark& landmark = landmarks_[slot];
        result.objects.push_back(
            {static_cast<int>(o), landmark.id, landmark.place, std::move(matches)});
      }
    }
    result.stats.matching.matched_pairs = static_cast<int64_t>(result.objects.size());
    // Place-level matches by exact search over each matched place.
    std::map<PlaceId, std::vector<int32_t>> places;
    for (const LandmarkMatch& m : result.objects) places[m.place];
    for (const auto& [place, unused] : places) {
      result.place_points[place] = ExactPlacePoints(query, place);
    }
    result.stats.candidate_places = static_cast<int64_t>(places.size());
    return result;
  }

  // The texture range of each query object; the range and colour filters are applied to every
  // neighbour FLANN returns (the same predicate the range tree answers, in O(1) per neighbour).
  Timer timer;
  std::vector<std::pair<int, int>> range(objects.size(), {INT32_MIN, INT32_MAX});
  if (options_.use_count_range) {
    for (size_t o = 0; o < objects.size(); ++o) {
      CountRange(objects[o].sift_count, options_.count_range_low, options_.count_range_high,
                 &range[o].first, &range[o].second);
    }
  }
  auto candidate = [&](int object, int32_t slot) {
    if (!objects[object].is_object) return false;
    const int count = landmarks_[slot].sift_count;
    return count >= range[object].first && count <= range[object].second &&
           CandidateByColour(objects[object], slot);
  };
  result.stats.filter_ms = timer.ElapsedMs();
  timer.Restart();
  NeighbourLists neighbours;
  descriptors_.Search(query.rows, options_.matching.knn, &neighbours);
  result.stats.search_ms = timer.ElapsedMs();
  timer.Restart();
  const std::vector<ObjectPair> pairs = MatchObjectPairs(
      query, neighbours,
      [this](int32_t slot) -> const cv::Mat& { return landmarks_[slot].descriptors; },
      [&](int object, int32_t slot) { return candidate(object, slot) && allowed_slot(slot); },
      options_.matching, &result.stats.matching);
  result.objects.reserve(pairs.size());
  result.stats.objects_ms = timer.ElapsedMs();
  timer.Restart();
  std::unordered_map<PlaceId, bool> matched_places;
  for (const ObjectPair& pair : pairs) {
    const Landmark& landmark = landmarks_[pair.owner];
    result.objects.push_back({pair.query_object, landmark.id, landmark.place, pair.matches});
    matched_places[landmark.place] = true;
  }
  if (options_.vote_places > 0) {
    // Distinctive votes: a query row votes for the place of its nearest allowed neighbour when
    // that neighbour passes the ratio test against the nearest neighbour of another location
    // (not the same robot within vote_window_seconds, which shows the same scene).
    const float ratio_squared =
        static_cast<float>(options_.matching.ratio * options_.matching.ratio);
    std::unordered_map<PlaceId, int> votes;
    for (int q = 0; q < query.size(); ++q) {
      const DescriptorIndex::Neighbour* first = nullptr;
      float other = -1;
      for (const DescriptorIndex::Neighbour& n : neighbours[q]) {
        if (!allowed_slot(n.owner)) continue;
        if (first == nullptr) {
          first = &n;
          continue;
        }
        if (!SameLocation(landmarks_[first->owner].place, landmarks_[n.owner].place)) {
          other = n.distance;
          break;
        }
      }
      if (first == nullptr) continue;
      if (other < 0) other = neighbours[q].back().distance;  // a lower bound on the true one
      if (first->distance < ratio_squared * other) ++votes[landmarks_[first->owner].place];
    }
    std::vector<std::pair<int, PlaceId>> ranked;
    for (const auto& [place, count] : votes) ranked.emplace_back(-count, place);
    std::sort(ranked.begin(), ranked.end());
    for (size_t i = 0; i < ranked.size() && static_cast<int>(i) < options_.vote_places; ++i) {
      const PlaceId place = ranked[i].second;
      matched_places[place] = true;
      // Votes merge neighbouring frames; let the geometric check choose among them.
      for (const PlaceId neighbour : VoteNeighbours(place, place_allowed)) {
        matched_places[neighbour] = true;
      }
    }
  }
  result.stats.candidate_places = static_cast<int64_t>(matched_places.size());

  // Place-level matches: group every query row's neighbours by place.
  const auto hits = GroupNeighbours(neighbours, [&](int, int32_t slot) -> int64_t {
    const PlaceId place = landmarks_[slot].place;
    return matched_places.count(place) > 0 ? place.value() : -1;
  });
  std::vector<int> distances;
  for (const auto& [place_value, list] : hits) {
    const PlaceId place(place_value);
    const std::vector<int32_t>& slots = slots_of_place_.at(place);
    const std::vector<GroupHit> passed =
        RatioTestHits(list, neighbours, options_.matching.ratio, [&](const GroupHit& hit) {
          float second = std::numeric_limits<float>::max();
          const uint8_t* q = query.rows.ptr<uint8_t>(hit.query);
          for (int32_t slot : slots) {
            const cv::Mat& d = landmarks_[slot].descriptors;
            distances.resize(static_cast<size_t>(d.rows));
            SquaredDistances(q, d, distances.data());
            for (int t = 0; t < d.rows; ++t) {
              if (slot == hit.owner && t == hit.train) continue;
              second = std::min(second, static_cast<float>(distances[t]));
            }
          }
          return second;
        });
    std::vector<PointMatch>& points = result.place_points[place];
    for (const GroupHit& hit : passed) {
      points.push_back(
          {query.object[hit.query], query.row_in_object[hit.query], hit.owner, hit.train, hit.d1});
    }
  }
  result.stats.places_ms = timer.ElapsedMs();
  if (options_.exact_places > 0) {
    timer.Restart();
    std::vector<std::pair<int64_t, PlaceId>> ranked;
    for (const auto& [place, points] : result.place_points) {
      ranked.emplace_back(-static_cast<int64_t>(points.size()), place);
    }
    std::sort(ranked.begin(), ranked.end());
    // The best places, then each one's nearest candidate places along its robot's route (so
    // that the frames of one stretch compete on equal matches).
    std::vector<PlaceId> chosen;
    for (size_t i = 0; i < ranked.size() && static_cast<int>(i) < options_.exact_places; ++i) {
      chosen.push_back(ranked[i].second);
    }
    const size_t best = chosen.size();
    for (size_t i = 0; i < best && options_.exact_route_neighbours > 0; ++i) {
      for (const PlaceId neighbour :
           RouteNeighbours(chosen[i], options_.exact_route_neighbours, result.place_points)) {
        if (std::find(chosen.begin(), chosen.end(), neighbour) == chosen.end()) {
          chosen.push_back(neighbour);
        }
      }
    }
    int64_t budget = options_.exact_max_comparisons;
    for (const PlaceId place : chosen) {
      const int64_t comparisons = PlaceDescriptorRows(place) * query.size();
      if (comparisons > budget) {
        ++result.stats.exact_skipped;
        continue;
      }
      budget -= comparisons;
      result.stats.exact_comparisons += comparisons;
      ++result.stats.exact_places;
      result.place_points[place] = ExactPlacePoints(query, place);
    }
    result.stats.exact_ms = timer.ElapsedMs();
  }
  return result;
}

std::vector<PlaceId> LandmarkIndex::RouteNeighbours(
    PlaceId place, int per_side, const std::map<PlaceId, std::vector<PointMatch>>& among) const {
  // The vote neighbours among the candidates come nearest in time first; keep the first
  // `per_side` on either side (the order of the route: capture time, then place id).
  const PlaceInfo& info = place_info_.at(place);
  int before = 0;
  int after = 0;
  std::vector<PlaceId> neighbours;
  for (const PlaceId other :
       VoteNeighbours(place, [&](PlaceId id) { return among.count(id) > 0; })) {
    const PlaceInfo& other_info = place_info_.at(other);
    int& taken =
        std::make_pair(other_info.utime, other.value()) < std::make_pair(info.utime, place.value())
            ? before
            : after;
    if (taken < per_side) {
      neighbours.push_back(other);
      ++taken;
    }
  }
  return neighbours;
}

int64_t LandmarkIndex::PlaceDescriptorRows(PlaceId place) const {
  int64_t rows = 0;
  for (int32_t slot : slots_of_place_.at(place)) {
    const cv::Mat& d = landmarks_[slot].descriptors;
    if (!d.empty()) rows += d.rows;  // a matrix may be empty with rows but no columns
  }
  return rows;
}

std::vector<PointMatch> LandmarkIndex::ExactPlacePoints(const StackedQuery& query,
                                                        PlaceId place) const {
  // The place's descriptors in one matrix, compared with every query row in turn: query rows
  // times the place's descriptors comparisons.
  const std::vector<int32_t>& slots = slots_of_place_.at(place);
  const int rows = static_cast<int>(PlaceDescriptorRows(place));
  cv::Mat stacked(rows, kDescriptorSize, CV_8U);
  std::vector<std::pair<int32_t, int>> origin;  // per stacked row: (slot, row in the landmark)
  origin.reserve(static_cast<size_t>(rows));
  for (int32_t slot : slots) {
    const cv::Mat& d = landmarks_[slot].descriptors;
    if (d.empty()) continue;
    d.copyTo(stacked.rowRange(static_cast<int>(origin.size()),
                              static_cast<int>(origin.size()) + d.rows));
    for (int t = 0; t < d.rows; ++t) origin.emplace_back(slot, t);
  }
  // Lowe's ratio test within the place; each stored row kept by its closest query row.
  std::vector<PointMatch> points;
  for (const DescriptorMatch& m : MatchRatioTest(query.rows, stacked, options_.matching.ratio)) {
    points.push_back({query.object[m.query], query.row_in_object[m.query], origin[m.train].first,
                      origin[m.train].second, static_cast<float>(m.distance)});
  }
  return points;
}

}  // namespace placerec
