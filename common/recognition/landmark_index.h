// Retrieval of stored landmark objects (pipeline step 8, seed §5.6): candidates are the stored
// objects whose SIFT count lies in [2n/3, 4n/3] for a query object with n keypoints (the range
// tree) and whose dominant colour invariant is within 0.2 (the colour filter); a candidate is
// the same object when more than 6 descriptors match with the ratio test.
//
// kExhaustive does exactly that: it enumerates the candidates with the range tree and matches
// each one. kFlann (the default) turns the cascade around so that its cost does not grow with
// the number of candidates: every query descriptor's nearest neighbours come from one FLANN
// index over all stored descriptors, and only neighbours in candidate objects (the same range
// and colour predicate, checked per neighbour) vote for and verify object pairs.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <tuple>
#include <unordered_map>
#include <vector>

#include <opencv2/core.hpp>

#include "common/recognition/colour_filter.h"
#include "common/recognition/descriptor_index.h"
#include "common/recognition/object_matcher.h"
#include "common/recognition/range_tree.h"
#include "common/recognition/types.h"

namespace placerec {

enum class IndexSearch {
  kFlann,       // FLANN nearest neighbours vote, exact ratio test verifies
  kExhaustive,  // exact ratio test against every candidate (seed §5.6 literally)
};

struct LandmarkIndexOptions {
  // Restrict candidates to SIFT counts in [low * n, high * n] (seed §5.6: 2/3 and 4/3).
  bool use_count_range = true;
  double count_range_low = 2.0 / 3.0;
  double count_range_high = 4.0 / 3.0;
  // Restrict candidates by dominant colour (seed §5.6).
  bool use_colour_filter = true;
  ColourFilterOptions colour;
  // Verification: more than 6 ratio-test matches (seed §5.6).
  ObjectMatchingOptions matching;
  DescriptorIndexOptions flann;
  IndexSearch search = IndexSearch::kFlann;
  // Besides places with an object-level match, check the places that collect the most
  // distinctive votes (at most this many; 0: only object-level candidates). A query descriptor
  // votes for the place of its nearest neighbour when it passes the ratio test against the
  // nearest neighbour seen at another location.
  int vote_places = 10;
  // Places of one robot taken within this many seconds of each other (capture time) count as
  // one location for the votes: they see the same scene, at any frame rate. A voted place
  // brings at most LandmarkIndex::kMaxVoteNeighbours of them as candidates (the nearest in time
  // that the caller allows), so a window wider than 3.2 s at 10 Hz is cut to the nearest 64.
  double vote_window_seconds = 3.0;
  // The candidate places with the most place-level matches from the neighbour lists (at most
  // this many, ties to the lower place id; 0: none, as in the seed, whose places are judged by
  // their object matches, §5.6) are matched again exactly: every query descriptor against every
  // descriptor of the place, with the ratio test within the place; these matches replace the
  // place's matches from the lists (the other candidates keep theirs). Where many stored
  // descriptors resemble a query descriptor (a large map, repeated texture, night), they crowd
  // the revisited place's own match out of the `matching.knn` nearest neighbours of the whole
  // map; the exact matching finds it again. Only candidate places with an entry in
  // IndexResult::place_points (a neighbour in some list) are ranked. Off by default: it also
  // lifts the frames a few metres along the route from the true one, which on small frames
  // scaled up (AnalyzerOptions' small_frame_width) then win loop closures (docs/results.md).
  int exact_places = 0;
  // Each of those places also brings this many of its robot's candidate places on either side
  // along the route (nearest in time, within vote_window_seconds), matched exactly too, so that
  // the frames of one stretch compete on equal terms for which is nearest to the query.
  int exact_route_neighbours = 1;
  // At most this many descriptor comparisons (query rows times a place's descriptors) per
  // lookup for exact_places: a place whose comparisons would pass what is left keeps its
  // matches from the lists. It bounds the step's time for frames and places with many
  // descriptors.
  int64_t exact_max_comparisons = 20000000;

  bool Check(std::string* error) const;
};

// What a query object brings to the index.
struct IndexQuery {
  int sift_count = 0;
  ColourSignature colour;
  cv::Mat descriptors;  // CV_8U x 128
  // False for descriptors that belong to no object (keypoints outside every object of the
  // frame): they vote for places and match at place level, but form no object pairs.
  bool is_object = true;
};

struct LandmarkMatch {
  int query_object = -1;
  LandmarkId landmark;
  PlaceId place;
  std::vector<DescriptorMatch> matches;  // query rows, rows of the landmark's descriptors
};

// A query descriptor matched to a stored descriptor of a candidate place: its nearest within
// that place, passing the ratio test against the place's other descriptors.
struct PointMatch {
  int query_object = -1;
  int query_row = -1;  // row within the query object
  int32_t slot = -1;   // the stored landmark (index slot)
  int train = -1;      // row within the landmark
  float distance = 0;  // squared Euclidean
};

struct IndexQueryStats {
  int64_t candidates = 0;  // kExhaustive: sum over query objects of candidate landmarks
  int64_t candidate_places = 0;
  ObjectMatchingStats matching;
  double filter_ms = 0;           // query ranges and filters
  double search_ms = 0;           // nearest neighbours of every query descriptor
  double objects_ms = 0;          // object pairs
  double places_ms = 0;           // votes and place-level matches
  double exact_ms = 0;            // exact place-level matches of the best places (exact_places)
  int64_t exact_places = 0;       // places matched exactly
  int64_t exact_comparisons = 0;  // descriptor comparisons they took
  int64_t exact_skipped = 0;      // places left to their lists by exact_max_comparisons
};

struct IndexResult {
  // Object-level matches: the seed's retrieval (§5.6), sorted by (query object, landmark).
  std::vector<LandmarkMatch> objects;
  // For every candidate place (an object-level match, or among the places with the most
  // distinctive votes and their neighbours, see `vote_places`): the query descriptors matched
  // into the place's landmarks with a ratio test over the whole place. These feed the geometric
  // check; they are more selective than matches inside single objects, whose second neighbours
  // are few. A voted place may have no object-level match at all. The places matched exactly
  // (`exact_places`) have every such match; the others those their neighbour lists hold.
  std::map<PlaceId, std::vector<PointMatch>> place_points;
  IndexQueryStats stats;
};

class LandmarkIndex {
 public:
  // A place chosen by the votes brings at most this many other places of its robot within the
  // vote window, nearest in time first (a 10 Hz camera's whole window of 3 s on each side): a
  // faster camera, or a robot whose clock stands still, does not make every place a candidate.
  static constexpr int kMaxVoteNeighbours = 64;
  // ... looked for among at most this many places of the window (some may not be allowed).
  static constexpr int kMaxVoteNeighbourSteps = 4 * kMaxVoteNeighbours;

  explicit LandmarkIndex(const LandmarkIndexOptions& options);

  // Registers a place before its landmarks are added.
  void AddPlace(const Place& place);

  // Adds a stored landmark (valid id and place, descriptors CV_8U x 128 with one keypoint per
  // row). Keeps a reference to the descriptor matrix.
  void Add(const Landmark& landmark) { Add(Landmark(landmark)); }
  void Add(Landmark&& landmark);
  // Makes room for this many landmarks in all (opening a map): saves the copies of every
  // landmark held that growing one at a time makes (cv::Mat cannot be moved without a possible
  // exception, so std::vector copies its landmarks when it grows).
  void Reserve(size_t landmarks) { landmarks_.reserve(landmarks); }

  // Matches each query object against the stored landmarks of places for which
  // `place_allowed` is true.
  IndexResult Query(const std::vector<IndexQuery>& objects,
                    const std::function<bool(PlaceId)>& place_allowed) const;

  // Slots (insertion order) of the landmarks that pass the texture and colour filters.
  std::vector<int32_t> Candidates(const IndexQuery& object) const;

  // The landmark stored in a slot, and the slot of a landmark id (-1 if absent).
  const Landmark& landmark(int32_t slot) const { return landmarks_[slot]; }
  int32_t SlotOf(LandmarkId id) const;
  // Slots of a place's landmarks (empty for an unknown place or one without landmarks).
  std::vector<int32_t> SlotsOfPlace(PlaceId place) const;

  // The nearest-neighbour index over every stored descriptor (for measurements, and
  // DescriptorIndex::SaveSnapshot).
  const DescriptorIndex& descriptor_index() const { return descriptors_; }
  // Opening a map: Add records descriptors without indexing them until FinishDescriptors, which
  // starts from the snapshot at `snapshot_path` if it fits (DescriptorIndex::FinishDeferred).
  // Query must not run in between.
  void DeferDescriptors() { descriptors_.DeferInsertion(); }
  SnapshotLoad FinishDescriptors(const std::string& snapshot_path) {
    return descriptors_.FinishDeferred(snapshot_path);
  }

  size_t num_landmarks() const { return landmarks_.size(); }
  size_t num_descriptors() const { return num_descriptors_; }
  const LandmarkIndexOptions& options() const { return options_; }

 private:
  bool CandidateByColour(const IndexQuery& object, int32_t slot) const;
  // Every query row's nearest descriptor within the place's landmarks that passes the ratio
  // test against the place's second nearest; each stored row kept by its closest query row.
  std::vector<PointMatch> ExactPlacePoints(const StackedQuery& query, PlaceId place) const;
  // The nearest `per_side` places of `place`'s robot before it and after it in time that are
  // keys of `among`, among its vote neighbours (VoteNeighbours).
  std::vector<PlaceId> RouteNeighbours(
      PlaceId place, int per_side, const std::map<PlaceId, std::vector<PointMatch>>& among) const;
  // Descriptors of the place's landmarks.
  int64_t PlaceDescriptorRows(PlaceId place) const;
  bool SameLocation(PlaceId a, PlaceId b) const;
  // The other places of `place`'s robot within the vote window that `place_allowed` accepts,
  // nearest in time first, at most kMaxVoteNeighbours.
  std::vector<PlaceId> VoteNeighbours(PlaceId place,
                                      const std::function<bool(PlaceId)>& place_allowed) const;
  int64_t VoteWindowUs() const { return static_cast<int64_t>(options_.vote_window_seconds * 1e6); }

  struct PlaceInfo {
    int robot = -1;
    int64_t utime = 0;
  };
  LandmarkIndexOptions options_;
  std::vector<Landmark> landmarks_;
  // Landmark id -> slot. Not a vector by id: ids need not be dense (a pruned map, a PostgreSQL
  // sequence moved on), and one large id would size it.
  std::unordered_map<int64_t, int32_t> slot_of_id_;
  std::unordered_map<PlaceId, std::vector<int32_t>> slots_of_place_;
  std::unordered_map<PlaceId, PlaceInfo> place_info_;
  std::set<std::tuple<int, int64_t, int64_t>> place_by_time_;  // (robot, utime, place id)
  std::unordered_map<std::string, int> robot_number_;
  RangeTree<int32_t> by_count_;
  DescriptorIndex descriptors_;
  size_t num_descriptors_ = 0;
};

}  // namespace placerec
