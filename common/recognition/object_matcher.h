// Object-to-object matching through a descriptor index (seed §5.3, §5.6). The query objects'
// descriptors are searched once in the index; each query descriptor's neighbour list then
// votes for (query object, stored object) pairs, and every pair with enough votes is verified
// with Lowe's ratio test inside the stored object. The test is decided from the neighbour list
// when it says enough (the second neighbour within the object is in the list, or the list's
// last distance already passes) and by exact distances otherwise. The same grouping of
// neighbour lists serves other groups of stored objects, such as all landmarks of one place.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <unordered_map>
#include <vector>

#include <opencv2/core.hpp>

#include "common/recognition/descriptor_index.h"
#include "common/recognition/descriptor_matching.h"

namespace placerec {

struct ObjectMatchingOptions {
  // Lowe's ratio test: nearest < ratio * second nearest within the candidate object.
  double ratio = 0.8;
  // Matched descriptors that make two objects the same. Landmark selection uses 6 ("at least
  // six pairs", seed §5.3); retrieval uses 7 ("more than 6", seed §5.6).
  int min_matches = 7;
  // Nearest neighbours fetched from the index per query descriptor.
  int knn = 16;
  // A (query object, stored object) pair is verified only when at least this many of the query
  // object's descriptors have a neighbour in the stored object.
  int min_votes = 3;
  // Verify a voted pair with the exact ratio test over every row of both objects instead of
  // only the query rows whose neighbour lists hold the stored object. Finds the matches whose
  // nearest neighbour within the object is crowded out of the list, at O(n m) cost per pair.
  bool exhaustive_verification = false;

  bool Check(std::string* error) const;
};

// The descriptors of all query objects stacked into one matrix for a single index search.
struct StackedQuery {
  cv::Mat rows;                    // CV_8U x 128
  std::vector<int> object;         // per row: its query object
  std::vector<int> row_in_object;  // per row: its row within that object

  static StackedQuery Stack(const std::vector<cv::Mat>& objects);
  int size() const { return rows.rows; }
};

using NeighbourLists = std::vector<std::vector<DescriptorIndex::Neighbour>>;

// A query row's nearest stored descriptor within one group of stored objects (an object, or a
// place's landmarks), with the second nearest distance within the group when the list holds it.
struct GroupHit {
  int query = -1;      // row of the stacked query
  int32_t owner = -1;  // stored object of the nearest descriptor
  int train = -1;      // its row within the owner
  float d1 = 0;        // squared distance to it
  float d2 = -1;       // second nearest within the group, -1 when not in the list
};

// Groups each query row's neighbours by `group(query_row, owner)` (-1 skips the neighbour) and
// keeps, per group, the first neighbour and the second distance. Keys are the group ids.
std::unordered_map<int64_t, std::vector<GroupHit>> GroupNeighbours(
    const NeighbourLists& neighbours, const std::function<int64_t(int, int32_t)>& group);

// Lowe's ratio test for a hit. When the list does not hold the second neighbour within the group
// and its last distance does not settle the test, `exact_second(hit)` must return the true
// second nearest squared distance within the group. Each stored row is matched at most once
// (the closest query row keeps it).
std::vector<GroupHit> RatioTestHits(const std::vector<GroupHit>& hits,
                                    const NeighbourLists& neighbours, double ratio,
                                    const std::function<float(const GroupHit&)>& exact_second);

struct ObjectPair {
  int query_object = -1;
  int32_t owner = -1;                    // the stored object's id in the index
  std::vector<DescriptorMatch> matches;  // query rows of the query object, train rows of owner
};

struct ObjectMatchingStats {
  int64_t query_descriptors = 0;
  int64_t candidate_pairs = 0;  // pairs that received a vote
  int64_t verified_pairs = 0;   // pairs checked with the ratio test
  int64_t matched_pairs = 0;
};

// Object pairs from neighbour lists of `query` in an index whose owners' descriptors are given
// by `owner_descriptors`; `allowed(q, owner)` filters pairs before any verification. Result
// sorted by (query object, owner).
std::vector<ObjectPair> MatchObjectPairs(
    const StackedQuery& query, const NeighbourLists& neighbours,
    const std::function<const cv::Mat&(int32_t owner)>& owner_descriptors,
    const std::function<bool(int query_object, int32_t owner)>& allowed,
    const ObjectMatchingOptions& options, ObjectMatchingStats* stats);

// Search + MatchObjectPairs in one call.
std::vector<ObjectPair> MatchObjects(
    const std::vector<cv::Mat>& query_objects, const DescriptorIndex& index,
    const std::function<const cv::Mat&(int32_t owner)>& owner_descriptors,
    const std::function<bool(int query_object, int32_t owner)>& allowed,
    const ObjectMatchingOptions& options, ObjectMatchingStats* stats);

}  // namespace placerec
