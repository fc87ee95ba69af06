#include "server/map_follower.h"

#include <chrono>
#include <memory>
#include <utility>
#include <vector>

#include "common/util/logging.h"

namespace placerec {

bool MapFollowerOptions::Check(std::string* error) const {
  if (!(retry_s > 0) || retry_s > 3600) {
    *error = "map follower retry_s must be positive and at most 3600 seconds";
    return false;
  }
  if (batch_places < 1 || wait_ms < 1 || wait_ms > 60000) {
    *error = "map follower batch_places must be >= 1 and wait_ms in [1, 60000]";
    return false;
  }
  return true;
}

MapFollower::MapFollower(std::string url, const PostgresStoreOptions& store,
                         const MapFollowerOptions& options, PlaceMap* map, PlaceId last_known,
                         std::function<void(const Place&)> on_added)
    : url_(std::move(url)),
      store_(store),
      options_(options),
      map_(map),
      on_added_(std::move(on_added)),
      last_(last_known) {}

MapFollower::~MapFollower() { Stop(); }

void MapFollower::Start() {
  if (thread_.joinable()) return;
  thread_ = std::thread([this] { Loop(); });
}

void MapFollower::Stop() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

bool MapFollower::CatchUp(PostgresChangeFeed* feed) {
  while (true) {
    StatusOr<std::vector<CommittedPlace>> batch = feed->FetchAfter(last_, options_.batch_places);
    if (!batch.ok()) {
      LOG(WARNING) << "map follower: " << batch.status().message();
      return false;
    }
    for (CommittedPlace& committed : *batch) {
      if (last_ < committed.place.id) last_ = committed.place.id;
      if (!committed.damage.ok()) {
        // Waiting for it would stall every later place for good; it stays out of this server's
        // index (a server starting on the map refuses it and says the same).
        LOG(ERROR) << "map follower: place " << committed.place.id.value()
                   << " of the shared map is damaged and is left out of this server's map; "
                   << "later places are followed: " << committed.damage.message();
        places_damaged_.fetch_add(1);
        continue;
      }
      const Place place = committed.place;
      if (map_->AddCommitted(place, std::move(committed.landmarks))) {
        places_added_.fetch_add(1);
        if (on_added_) on_added_(place);
      }
    }
    if (static_cast<int>(batch->size()) < options_.batch_places) return true;
  }
}

void MapFollower::Loop() {
  std::unique_ptr<PostgresChangeFeed> feed;
  bool outage_logged = false;
  // Waits retry_s (or until Stop); false when stopping.
  const auto pause = [this] {
    std::unique_lock lock(mutex_);
    wake_.wait_for(lock, std::chrono::duration<double>(options_.retry_s), [this] { return stop_; });
    return !stop_;
  };
  const auto stopping = [this] {
    std::lock_guard lock(mutex_);
    return stop_;
  };
  while (!stopping()) {
    if (feed == nullptr) {
      StatusOr<std::unique_ptr<PostgresChangeFeed>> opened = PostgresChangeFeed::Open(url_, store_);
      if (!opened.ok()) {
        if (!outage_logged) {
          LOG(WARNING) << "map follower cannot reach the database, retrying every "
                       << options_.retry_s << " s: " << opened.status().message();
          outage_logged = true;
        }
        pause();
        continue;
      }
      feed = std::move(*opened);
      // Listening before catching up: a place committed in between is read now or notified.
      if (!CatchUp(feed.get())) {
        feed.reset();
        outage_logged = true;
        pause();
        continue;
      }
      connected_.store(true);
      if (outage_logged) {
        LOG(INFO) << "map follower reconnected; caught up to place " << last_.value();
      }
      outage_logged = false;
      continue;
    }
    StatusOr<int> arrived = feed->Wait(options_.wait_ms);
    if (arrived.ok() && *arrived == 0) continue;
    if (!arrived.ok() || !CatchUp(feed.get())) {
      if (!arrived.ok()) LOG(WARNING) << "map follower: " << arrived.status().message();
      connected_.store(false);
      feed.reset();
      outage_logged = true;
      pause();
    }
  }
  connected_.store(false);
}

}  // namespace placerec
