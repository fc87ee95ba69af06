#include "common/recognition/object_matcher.h"

#include <algorithm>
#include <limits>

#include "common/features/features.h"
#include "common/util/logging.h"

namespace placerec {

bool ObjectMatchingOptions::Check(std::string* error) const {
  if (ratio <= 0 || ratio > 1) {
    *error = "matching ratio must be in (0, 1]";
    return false;
  }
  if (min_matches < 1) {
    *error = "matching min_matches must be at least 1";
    return false;
  }
  if (knn < 1 || knn > 1000) {
    *error = "matching knn must be in [1, 1000]";
    return false;
  }
  if (min_votes < 1) {
    *error = "matching min_votes must be at least 1";
    return false;
  }
  return true;
}

StackedQuery StackedQuery::Stack(const std::vector<cv::Mat>& objects) {
  StackedQuery stacked;
  int total = 0;
  for (const cv::Mat& d : objects) total += d.rows;
  stacked.rows.create(total, kDescriptorSize, CV_8U);
  stacked.object.reserve(total);
  stacked.row_in_object.reserve(total);
  int row = 0;
  for (size_t o = 0; o < objects.size(); ++o) {
    const cv::Mat& d = objects[o];
    if (d.empty()) continue;
    CHECK_EQ(d.type(), CV_8U);
    d.copyTo(stacked.rows.rowRange(row, row + d.rows));
    for (int r = 0; r < d.rows; ++r) {
      stacked.object.push_back(static_cast<int>(o));
      stacked.row_in_object.push_back(r);
    }
    row += d.rows;
  }
  return stacked;
}

std::unordered_map<int64_t, std::vector<GroupHit>> GroupNeighbours(
    const NeighbourLists& neighbours, const std::function<int64_t(int, int32_t)>& group) {
  std::unordered_map<int64_t, std::vector<GroupHit>> hits;
  // Per query row: group -> index of its hit in hits[group] (or -1 when skipped).
  std::vector<std::pair<int64_t, int64_t>> seen;
  for (int q = 0; q < static_cast<int>(neighbours.size()); ++q) {
    seen.clear();
    for (const DescriptorIndex::Neighbour& n : neighbours[q]) {
      const int64_t key = group(q, n.owner);
      if (key < 0) continue;
      auto it =
          std::find_if(seen.begin(), seen.end(), [key](const auto& s) { return s.first == key; });
      if (it != seen.end()) {
        GroupHit& hit = hits[key][it->second];
        if (hit.d2 < 0) hit.d2 = n.distance;
        continue;
      }
      std::vector<GroupHit>& list = hits[key];
      seen.emplace_back(key, static_cast<int64_t>(list.size()));
      list.push_back({q, n.owner, n.row, n.distance, -1.0f});
    }
  }
  return hits;
}

std::vector<GroupHit> RatioTestHits(const std::vector<GroupHit>& hits,
                                    const NeighbourLists& neighbours, double ratio,
                                    const std::function<float(const GroupHit&)>& exact_second) {
  const float ratio_squared = static_cast<float>(ratio * ratio);
  std::vector<GroupHit> passed;
  std::unordered_map<uint64_t, size_t> taken;  // (owner, train) -> index in passed
  for (const GroupHit& hit : hits) {
    float d2 = hit.d2;
    if (d2 < 0) {
      // The second neighbour within the group is not in the list, so it is at least as far as
      // the list's last entry; when that already passes, so does the true one.
      const float bound = neighbours[hit.query].back().distance;
      d2 = hit.d1 < ratio_squared * bound ? std::numeric_limits<float>::max() : exact_second(hit);
    }
    if (!(hit.d1 < ratio_squared * d2)) continue;
    // One query row per stored row: the closest keeps it.
    const uint64_t stored = (static_cast<uint64_t>(static_cast<uint32_t>(hit.owner)) << 32) |
                            static_cast<uint32_t>(hit.train);
    const auto [it, inserted] = taken.emplace(stored, passed.size());
    if (inserted) {
      passed.push_back(hit);
    } else if (hit.d1 < passed[it->second].d1) {
      passed[it->second] = hit;
    }
  }
  return passed;
}

std::vector<ObjectPair> MatchObjectPairs(
    const StackedQuery& query, const NeighbourLists& neighbours,
    const std::function<const cv::Mat&(int32_t owner)>& owner_descriptors,
    const std::function<bool(int query_object, int32_t owner)>& allowed,
    const ObjectMatchingOptions& options, ObjectMatchingStats* stats) {
  ObjectMatchingStats local;
  local.query_descriptors = query.size();
  std::vector<ObjectPair> pairs;
  const auto hits = GroupNeighbours(neighbours, [&](int q, int32_t owner) -> int64_t {
    const int object = query.object[q];
    if (!allowed(object, owner)) return -1;
    return (static_cast<int64_t>(object) << 32) | static_cast<uint32_t>(owner);
  });
  local.candidate_pairs = static_cast<int64_t>(hits.size());

  std::vector<int64_t> keys;
  for (const auto& [key, list] : hits) {
    if (static_cast<int>(list.size()) >= options.min_votes) keys.push_back(key);
  }
  std::sort(keys.begin(), keys.end());
  for (int64_t key : keys) {
    const int object = static_cast<int>(key >> 32);
    const int32_t owner = static_cast<int32_t>(key & 0xffffffff);
    const cv::Mat& train = owner_descriptors(owner);
    ++local.verified_pairs;
    std::vector<DescriptorMatch> matches;
    if (options.exhaustive_verification) {
      const int first = static_cast<int>(
          std::find(query.object.begin(), query.object.end(), object) - query.object.begin());
      int count = 0;
      while (first + count < query.size() && query.object[first + count] == object) ++count;
      matches = MatchRatioTest(query.rows.rowRange(first, first + count), train, options.ratio);
    } else {
      std::vector<int> distances;
      const std::vector<GroupHit> passed =
          RatioTestHits(hits.at(key), neighbours, options.ratio, [&](const GroupHit& hit) {
            float second = std::numeric_limits<float>::max();
            distances.resize(static_cast<size_t>(train.rows));
            SquaredDistances(query.rows.ptr<uint8_t>(hit.query), train, distances.data());
            for (int t = 0; t < train.rows; ++t) {
              if (t != hit.train) second = std::min(second, static_cast<float>(distances[t]));
            }
            return second;
          });
      for (const GroupHit& hit : passed) {
        matches.push_back(
            {query.row_in_object[hit.query], hit.train, static_cast<int>(hit.d1 + 0.5f)});
      }
    }
    if (static_cast<int>(matches.size()) < options.min_matches) continue;
    pairs.push_back({object, owner, std::move(matches)});
  }
  local.matched_pairs = static_cast<int64_t>(pairs.size());
  if (stats != nullptr) *stats = local;
  return pairs;
}

std::vector<ObjectPair> MatchObjects(
    const std::vector<cv::Mat>& query_objects, const DescriptorIndex& index,
    const std::function<const cv::Mat&(int32_t owner)>& owner_descriptors,
    const std::function<bool(int query_object, int32_t owner)>& allowed,
    const ObjectMatchingOptions& options, ObjectMatchingStats* stats) {
  if (index.size() == 0 || query_objects.empty()) {
    if (stats != nullptr) *stats = ObjectMatchingStats();
    return {};
  }
  const StackedQuery query = StackedQuery::Stack(query_objects);
  NeighbourLists neighbours;
  index.Search(query.rows, options.knn, &neighbours);
  return MatchObjectPairs(query, neighbours, owner_descriptors, allowed, options, stats);
}

}  // namespace placerec
