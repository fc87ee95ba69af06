// The shared landmark map of a site: the persistent store plus the in-memory index built from
// it. Opening a map streams every stored landmark back into the index. Thread-safe: lookups run
// concurrently, an insert waits for them and commits to the store before the index sees it.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "common/recognition/landmark_index.h"
#include "common/recognition/loop_decision.h"
#include "common/recognition/recent_past.h"
#include "common/recognition/seed_decision.h"
#include "common/recognition/types.h"
#include "common/storage/landmark_store.h"
#include "common/util/status.h"

namespace placerec {

struct MapCounts {
  int64_t places = 0;
  int64_t landmarks = 0;
  int64_t descriptors = 0;
};

// What a frame looks up: its objects and where their descriptors sit in the frame.
struct MapLookup {
  RecentPastFilter recent;  // the querying robot, its frame's time and its recent past
  std::vector<IndexQuery> objects;
  std::vector<std::vector<cv::KeyPoint>> object_keypoints;  // per object, per descriptor row
  int image_width = 0;                                      // processed frame width, pixels
};

struct MapLookupResult {
  std::vector<PlaceMatch> places;  // best first
  // LookupSeed: every object-level match, (query object, stored landmark).
  std::vector<std::pair<int, LandmarkId>> object_matches;
  IndexQueryStats stats;
  double index_ms = 0;    // candidate filtering and descriptor verification
  double ranking_ms = 0;  // voting and geometric verification
};

class PlaceMap {
 public:
  // Takes over `store` and loads it into a new index.
  static StatusOr<std::unique_ptr<PlaceMap>> Open(std::unique_ptr<LandmarkStore> store,
                                                  const LandmarkIndexOptions& index_options);

  MapLookupResult Lookup(const MapLookup& lookup, const LoopDecisionOptions& options) const;
  // The seed's lookup and decision (seed_decision.h, §5.7 steps 5-6): object-level matches of
  // the frame's landmarks (lookup.objects, one per landmark) against every stored object, ranked
  // by the scene sets of the matched objects. `loop` receives the step-6 decision.
  MapLookupResult LookupSeed(const MapLookup& lookup, const SeedLoopOptions& options,
                             int max_matches, bool* loop) const;

  // Commits the place and its landmarks to the store (assigning ids), then indexes them; the
  // place joins the scene sets of place->seen_landmarks. On error nothing changes.
  Status Insert(Place* place, std::vector<Landmark>* landmarks);

  // A place's thumbnail (JPEG bytes, LandmarkStore::LoadThumbnail); empty when it has none.
  StatusOr<std::vector<uint8_t>> LoadThumbnail(PlaceId place) const;
  // A place's stored landmarks with ids, boxes and classes only (descriptors left out); empty for
  // an unknown place.
  std::vector<Landmark> LandmarkOutlines(PlaceId place) const;

  // Indexes a place (with its landmarks) that is already committed to the store, e.g. by another
  // server on the same PostgreSQL map; a place the map holds already is left alone. Whether the
  // place was new to the map.
  bool AddCommitted(const Place& place, std::vector<Landmark>&& landmarks);

  // For a map several servers share: from now on Insert commits, then waits until the place comes
  // back through AddCommitted (the server's follower reads every new place in id order), so that
  // every server grows its index in the same order (id order, as a map loaded from the store) and
  // answers alike. A place not back within `timeout` is indexed by Insert itself (out of order).
  void IndexThroughFollower(std::chrono::milliseconds timeout);

  MapCounts Counts() const;
  // The in-memory index (for measurements; not to be used while inserts may run).
  const LandmarkIndex& index() const { return index_; }
  // Calls `visit` for every place in the map (in no particular order), under the map's read lock:
  // `visit` must not call back into the map.
  void ForEachPlace(const std::function<void(const Place&)>& visit) const;
  // The place `robot` stored as its frame `sequence` captured at `utime`, if there is one: what a
  // frame sent again was stored as. A place whose stored time lay outside 0 .. kMaxUtime (an old
  // map's; used in memory as the nearest bound) is never one: no frame of such a time is accepted.
  // A pass over every place.
  std::optional<Place> FindStored(const std::string& robot, int64_t sequence, int64_t utime) const;
  // Views of `robot`'s recent past (RecentPast::Resume): of its places with sequences below
  // `before_sequence` captured in [from_utime, to_utime], the last (by sequence) and those
  // captured at most `span_us` before it, at most `max_places` of them, oldest first; each with
  // up to `max_descriptors` of its landmarks' descriptors. A pass over every place.
  std::vector<StoredView> StoredViews(const std::string& robot, int64_t before_sequence,
                                      int64_t from_utime, int64_t to_utime, int64_t span_us,
                                      int max_places, int max_descriptors) const;
  StatusOr<uint64_t> Checksum() const;
  std::string Describe() const;
  // Milliseconds Open spent loading the store and building the index.
  double open_ms() const { return open_ms_; }
  // What Open did with the descriptor index snapshot beside the map.
  const SnapshotLoad& snapshot_load() const { return snapshot_load_; }

  // Writes the descriptor index snapshot beside the map (LandmarkStore::IndexSnapshotPath), so
  // that the next Open loads the tree instead of growing it again; lookups go on meanwhile,
  // inserts wait. Skipped (ok, *written false) when the store keeps no snapshot, the index is
  // not FLANN's (kHnsw has no snapshot) or the snapshot on disk already covers the whole index.
  // `written` may be null.
  Status SaveIndexSnapshot(bool* written = nullptr);

 private:
  PlaceMap(std::unique_ptr<LandmarkStore> store, const LandmarkIndexOptions& index_options);

  // Indexes a committed place; the caller holds mutex_ exclusively.
  void IndexCommitted(const Place& place, const std::vector<Landmark>& landmarks);

  mutable std::shared_mutex mutex_;
  // Held by Insert from its commit until its place is indexed (not while waiting for a
  // follower): one commit at a time, indexed in commit order.
  std::mutex insert_mutex_;
  // Signalled by AddCommitted, for Insert's wait (IndexThroughFollower).
  std::condition_variable_any indexed_;
  // Zero: Insert indexes its place itself; otherwise how long it waits for the follower
  // (milliseconds).
  std::atomic<int64_t> follower_timeout_ms_{0};
  std::unique_ptr<LandmarkStore> store_;
  LandmarkIndex index_;
  std::unordered_map<PlaceId, Place> places_;
  // Places whose stored capture time lay out of range (places_ holds them with the nearest bound).
  std::unordered_set<PlaceId> time_out_of_range_;
  // Per stored landmark, the later places that saw it again (Place::seen_landmarks).
  std::unordered_map<LandmarkId, std::vector<PlaceId>> seen_at_;
  double open_ms_ = 0;
  SnapshotLoad snapshot_load_;
  // Serialises SaveIndexSnapshot calls; guards snapshot_descriptors_.
  std::mutex snapshot_mutex_;
  // Descriptors the snapshot on disk covers, as far as this process knows (-1: unknown).
  int64_t snapshot_descriptors_ = -1;
};

}  // namespace placerec
