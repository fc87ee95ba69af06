#include "common/pipeline/place_map.h"

#include <algorithm>
#include <exception>
#include <mutex>
#include <utility>

#include "common/util/logging.h"
#include "common/util/timer.h"

namespace placerec {

PlaceMap::PlaceMap(std::unique_ptr<LandmarkStore> store, const LandmarkIndexOptions& index_options)
    : store_(std::move(store)), index_(index_options) {}

namespace {

// The place with its capture time moved into 0 .. kMaxUtime. A map written before times were
// checked at intake (or by such a server on a shared map) may hold any time; the differences the
// map takes between times (vote windows, a robot's recent past) must not overflow. The store
// keeps what it holds.
Place WithCaptureTimeInRange(const Place& place) {
  if (CheckCaptureTime(place.utime).ok()) return place;
  LOG(WARNING) << "place " << place.id.value() << " of robot '" << place.robot
               << "' has capture time " << place.utime << " us, outside 0 .. " << kMaxUtime
               << " us: used as " << ClampCaptureTime(place.utime)
               << " (the map file keeps it; placerec-map prune --robot, or --before for a time "
                  "before 0, drops it from a SQLite map)";
  Place bounded = place;
  bounded.utime = ClampCaptureTime(place.utime);
  return bounded;
}

}  // namespace

StatusOr<std::unique_ptr<PlaceMap>> PlaceMap::Open(std::unique_ptr<LandmarkStore> store,
                                                   const LandmarkIndexOptions& index_options) {
  CHECK(store != nullptr);
  Timer timer;
  std::unique_ptr<PlaceMap> map(new PlaceMap(std::move(store), index_options));
  // The descriptors are indexed once all are known: then the snapshot can be judged.
  map->index_.DeferDescriptors();
  PLACEREC_RETURN_IF_ERROR(map->store_->LoadPlaces([&map](const Place& stored) {
    const Place place = WithCaptureTimeInRange(stored);
    if (place.utime != stored.utime) map->time_out_of_range_.insert(place.id);
    map->places_[place.id] = place;
    map->index_.AddPlace(place);
    for (const LandmarkId seen : place.seen_landmarks) map->seen_at_[seen].push_back(place.id);
  }));
  // Room for the landmarks the places announce. A damaged count must not stop the map from
  // opening: the reservation is only a hint, and a failed one leaves the index to grow as it goes.
  size_t landmarks = 0;
  for (const auto& [id, place] : map->places_) landmarks += std::max(place.num_landmarks, 0);
  try {
    map->index_.Reserve(landmarks);
  } catch (const std::exception& e) {
    LOG(WARNING) << "cannot reserve room for " << landmarks << " landmarks (" << e.what()
                 << "): the places' landmark counts may be damaged";
  }
  Status status;
  PLACEREC_RETURN_IF_ERROR(map->store_->LoadLandmarks([&map, &status](Landmark&& landmark) {
    if (!status.ok()) return;
    if (map->places_.count(landmark.place) == 0) {
      status =
          Status::IoError("landmark " + std::to_string(landmark.id.value()) +
                          " refers to missing place " + std::to_string(landmark.place.value()));
      return;
    }
    map->index_.Add(std::move(landmark));
  }));
  PLACEREC_RETURN_IF_ERROR(status);
  const double load_ms = timer.ElapsedMs();
  map->snapshot_load_ = map->index_.FinishDescriptors(map->store_->IndexSnapshotPath());
  if (map->snapshot_load_.used && map->snapshot_load_.inserted_points == 0) {
    map->snapshot_descriptors_ = static_cast<int64_t>(map->index_.num_descriptors());
  }
  map->open_ms_ = timer.ElapsedMs();
  LOG(INFO) << "opened " << map->store_->Describe() << ": " << map->places_.size() << " places, "
            << map->index_.num_landmarks() << " landmarks, " << map->index_.num_descriptors()
            << " descriptors in " << map->open_ms_ << " ms (store " << load_ms
            << " ms, index snapshot " << map->snapshot_load_.load_ms << " ms, "
            << map->snapshot_load_.inserted_points << " descriptors inserted in "
            << map->snapshot_load_.insert_ms << " ms)";
  return map;
}

Status PlaceMap::SaveIndexSnapshot(bool* written) {
  if (written != nullptr) *written = false;
  const std::string path = store_->IndexSnapshotPath();
  if (path.empty() || index_.options().flann.method != DescriptorSearch::kFlann) {
    return Status::Ok();
  }
  std::lock_guard<std::mutex> saving(snapshot_mutex_);
  // Readers only: lookups go on, inserts (which take the lock exclusively) wait.
  std::shared_lock lock(mutex_);
  const auto descriptors = static_cast<int64_t>(index_.num_descriptors());
  if (descriptors == snapshot_descriptors_ || descriptors == 0) return Status::Ok();
  Timer timer;
  PLACEREC_RETURN_IF_ERROR(index_.descriptor_index().SaveSnapshot(path));
  snapshot_descriptors_ = descriptors;
  if (written != nullptr) *written = true;
  LOG(INFO) << "wrote " << path << " (" << descriptors << " descriptors) in " << timer.ElapsedMs()
            << " ms";
  return Status::Ok();
}

MapLookupResult PlaceMap::Lookup(const MapLookup& lookup,
                                 const LoopDecisionOptions& options) const {
  std::shared_lock lock(mutex_);
  MapLookupResult result;
  Timer timer;
  const IndexResult found = index_.Query(lookup.objects, [&](PlaceId id) {
    const auto it = places_.find(id);
    return it != places_.end() &&
           lookup.recent.Allows(it->second.robot, it->second.sequence, it->second.utime);
  });
  result.stats = found.stats;
  result.index_ms = timer.ElapsedMs();
  timer.Restart();
  result.places = RankPlaces(
      found, lookup.object_keypoints, lookup.image_width, index_,
      [this](PlaceId id) -> const Place* {
        const auto it = places_.find(id);
        return it == places_.end() ? nullptr : &it->second;
      },
      options);
  result.ranking_ms = timer.ElapsedMs();
  return result;
}

Status PlaceMap::Insert(Place* place, std::vector<Landmark>* landmarks) {
  const std::chrono::milliseconds timeout(follower_timeout_ms_.load());
  if (timeout.count() <= 0) {
    // One insert at a time, so that places are indexed in the order the store numbers them (as a
    // reopened map holds them); lookups go on while the store commits.
    std::lock_guard<std::mutex> inserting(insert_mutex_);
    PLACEREC_RETURN_IF_ERROR(store_->AddPlace(place, landmarks));
    std::unique_lock lock(mutex_);
    if (places_.count(place->id) == 0) IndexCommitted(*place, *landmarks);
    return Status::Ok();
  }
  // The store serialises its own calls; lookups go on while it commits.
  PLACEREC_RETURN_IF_ERROR(store_->AddPlace(place, landmarks));
  std::unique_lock lock(mutex_);
  if (indexed_.wait_for(lock, timeout, [&] { return places_.count(place->id) > 0; })) {
    return Status::Ok();
  }
  LOG(WARNING) << "place " << place->id.value()
               << " did not come back through the map follower within " << timeout.count()
               << " ms; indexed out of id order";
  IndexCommitted(*place, *landmarks);
  return Status::Ok();
}

void PlaceMap::IndexCommitted(const Place& committed, const std::vector<Landmark>& landmarks) {
  const Place place = WithCaptureTimeInRange(committed);
  if (place.utime != committed.utime) time_out_of_range_.insert(place.id);
  places_[place.id] = place;
  places_[place.id].thumbnail.clear();  // in the store only: LoadThumbnail
  index_.AddPlace(place);
  for (const Landmark& landmark : landmarks) index_.Add(landmark);
  for (const LandmarkId seen : place.seen_landmarks) seen_at_[seen].push_back(place.id);
}

void PlaceMap::IndexThroughFollower(std::chrono::milliseconds timeout) {
  follower_timeout_ms_.store(timeout.count());
}

bool PlaceMap::AddCommitted(const Place& place, std::vector<Landmark>&& landmarks) {
  std::unique_lock lock(mutex_);
  // A place Insert committed through this map may come back here too; it is indexed once.
  if (places_.count(place.id) > 0) return false;
  IndexCommitted(place, landmarks);
  indexed_.notify_all();
  return true;
}

MapLookupResult PlaceMap::LookupSeed(const MapLookup& lookup, const SeedLoopOptions& options,
                                     int max_matches, bool* loop) const {
  std::shared_lock lock(mutex_);
  MapLookupResult result;
  Timer timer;
  // Every stored object is a candidate (step 5); the time gap applies to the scenes (step 6).
  const IndexResult found = index_.Query(lookup.objects, [](PlaceId) { return true; });
  result.stats = found.stats;
  for (const LandmarkMatch& match : found.objects) {
    result.object_matches.emplace_back(match.query_object, match.landmark);
  }
  result.index_ms = timer.ElapsedMs();
  timer.Restart();
  result.places = SeedRankPlaces(
      found.objects, static_cast<int>(lookup.objects.size()),
      [this](LandmarkId id) {
        std::vector<PlaceId> scenes;
        const int32_t slot = index_.SlotOf(id);
        if (slot >= 0) scenes.push_back(index_.landmark(slot).place);
        const auto it = seen_at_.find(id);
        if (it != seen_at_.end()) scenes.insert(scenes.end(), it->second.begin(), it->second.end());
        return scenes;
      },
      [this](PlaceId id) -> const Place* {
        const auto it = places_.find(id);
        return it == places_.end() ? nullptr : &it->second;
      },
      [&lookup](const Place& place) {
        return lookup.recent.Allows(place.robot, place.sequence, place.utime);
      },
      options, max_matches, loop);
  for (PlaceMatch& match : result.places) match.landmark_classes = MatchedClasses(match, index_);
  result.ranking_ms = timer.ElapsedMs();
  return result;
}

StatusOr<std::vector<uint8_t>> PlaceMap::LoadThumbnail(PlaceId place) const {
  // The store serialises its own calls; no map lock needed.
  return store_->LoadThumbnail(place);
}

std::vector<Landmark> PlaceMap::LandmarkOutlines(PlaceId place) const {
  std::shared_lock lock(mutex_);
  std::vector<Landmark> outlines;
  for (const int32_t slot : index_.SlotsOfPlace(place)) {
    const Landmark& stored = index_.landmark(slot);
    Landmark outline;
    outline.id = stored.id;
    outline.place = stored.place;
    outline.box = stored.box;
    outline.object_class = stored.object_class;
    outline.class_confidence = stored.class_confidence;
    outlines.push_back(std::move(outline));
  }
  return outlines;
}

MapCounts PlaceMap::Counts() const {
  std::shared_lock lock(mutex_);
  MapCounts counts;
  counts.places = static_cast<int64_t>(places_.size());
  counts.landmarks = static_cast<int64_t>(index_.num_landmarks());
  counts.descriptors = static_cast<int64_t>(index_.num_descriptors());
  return counts;
}

void PlaceMap::ForEachPlace(const std::function<void(const Place&)>& visit) const {
  std::shared_lock lock(mutex_);
  for (const auto& [id, place] : places_) visit(place);
}

std::optional<Place> PlaceMap::FindStored(const std::string& robot, int64_t sequence,
                                          int64_t utime) const {
  std::shared_lock lock(mutex_);
  for (const auto& [id, place] : places_) {
    if (place.sequence == sequence && place.utime == utime && place.robot == robot &&
        time_out_of_range_.count(id) == 0) {
      return place;
    }
  }
  return std::nullopt;
}

std::vector<StoredView> PlaceMap::StoredViews(const std::string& robot, int64_t before_sequence,
                                              int64_t from_utime, int64_t to_utime, int64_t span_us,
                                              int max_places, int max_descriptors) const {
  std::shared_lock lock(mutex_);
  std::vector<const Place*> chosen;
  for (const auto& [id, place] : places_) {
    if (place.robot == robot && place.sequence < before_sequence && place.utime >= from_utime &&
        place.utime <= to_utime) {
      chosen.push_back(&place);
    }
  }
  std::sort(chosen.begin(), chosen.end(),
            [](const Place* a, const Place* b) { return a->sequence < b->sequence; });
  // The robot's views when it stored its last place: those captured shortly before (the tracker
  // leaves a view once unseen for a while; a robot that stood still stored one place).
  if (!chosen.empty()) {
    const int64_t last = chosen.back()->utime;
    chosen.erase(std::remove_if(chosen.begin(), chosen.end(),
                                [&](const Place* p) { return p->utime < last - span_us; }),
                 chosen.end());
  }
  if (static_cast<int>(chosen.size()) > max_places) {
    chosen.erase(chosen.begin(), chosen.end() - max_places);
  }
  std::vector<StoredView> views;
  for (const Place* place : chosen) {
    StoredView view;
    view.sequence = place->sequence;
    view.utime = place->utime;
    std::vector<cv::Mat> rows;
    for (const int32_t slot : index_.SlotsOfPlace(place->id)) {
      const Landmark& landmark = index_.landmark(slot);
      for (int r = 0;
           r < landmark.descriptors.rows && static_cast<int>(view.angles.size()) < max_descriptors;
           ++r) {
        rows.push_back(landmark.descriptors.row(r));
        view.angles.push_back(landmark.keypoints[r].angle);
      }
    }
    if (!rows.empty()) cv::vconcat(rows, view.descriptors);
    views.push_back(std::move(view));
  }
  return views;
}

StatusOr<uint64_t> PlaceMap::Checksum() const {
  std::shared_lock lock(mutex_);
  return store_->Checksum();
}

std::string PlaceMap::Describe() const { return store_->Describe(); }

}  // namespace placerec
