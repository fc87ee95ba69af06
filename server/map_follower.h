// Keeps this server's in-memory map in step with the places other servers commit to the same
// PostgreSQL map (DESIGN.md "Architecture"; common/storage/postgres_store.h). A thread of its own
// LISTENs for the NOTIFY each insert sends, fetches the places above the last one it has seen and
// indexes them (PlaceMap::AddCommitted); on (re)connecting it first catches up the same way, so a
// notification lost while the connection was down costs nothing. A lost connection is retried
// every `retry_s` until Stop(). A place whose rows do not read back whole is left out (logged),
// so that it does not hold back the places after it.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

#include "common/pipeline/place_map.h"
#include "common/storage/postgres_store.h"

namespace placerec {

struct MapFollowerOptions {
  // Seconds between two attempts to reach the database after the connection was lost.
  double retry_s = 0.5;
  // Places read per query when catching up.
  int batch_places = 256;
  // Milliseconds one wait for notifications lasts before the thread looks at Stop().
  int wait_ms = 100;

  bool Check(std::string* error) const;
};

class MapFollower {
 public:
  // Follows the map at `url` into `map` from the places above `last_known` on. `on_added` runs
  // (on the follower's thread) for every place it added to `map`. `map` must outlive the
  // follower.
  MapFollower(std::string url, const PostgresStoreOptions& store, const MapFollowerOptions& options,
              PlaceMap* map, PlaceId last_known, std::function<void(const Place&)> on_added);
  ~MapFollower();  // Stop()

  void Start();
  // Returns once the thread has ended (within about options.wait_ms).
  void Stop();

  // Places this follower added to the map so far.
  int64_t places_added() const { return places_added_.load(); }
  // Places of the shared map that did not read back whole, left out (logged as errors).
  int64_t places_damaged() const { return places_damaged_.load(); }
  // Whether the follower is connected and listening now.
  bool connected() const { return connected_.load(); }

 private:
  void Loop();
  // Fetches and indexes every place above last_; false (and logs) when the connection failed.
  bool CatchUp(PostgresChangeFeed* feed);

  const std::string url_;
  const PostgresStoreOptions store_;
  const MapFollowerOptions options_;
  PlaceMap* map_;
  std::function<void(const Place&)> on_added_;
  PlaceId last_;  // used by the thread only
  std::atomic<int64_t> places_added_{0};
  std::atomic<int64_t> places_damaged_{0};
  std::atomic<bool> connected_{false};
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;  // under mutex_
  std::thread thread_;
};

}  // namespace placerec
