// PostgreSQL implementation of LandmarkStore (DESIGN.md "Architecture"): one site's map shared by
// several servers. Same tables, BLOB encodings (blob_codec.h), checks and digest (checksum.h) as
// the SQLite store, the schema version of schema.h in table `meta`. Each place is committed in one
// transaction before AddPlace returns; that transaction also sends NOTIFY on
// kPostgresPlacesChannel with the new place id, so that the other servers' change feeds
// (PostgresChangeFeed) fetch it. Inserts take one advisory lock per map for their transaction, so
// place ids become visible in increasing order: a reader that has seen place n has seen every
// place below n, and "every place above the last one seen" is an exact catch-up query.
//
// A lost connection makes the calls fail with IoError; the next call connects again.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "common/recognition/types.h"
#include "common/storage/landmark_store.h"
#include "common/util/status.h"

namespace placerec {

// The NOTIFY channel of new places; the payload is the place id in decimal.
constexpr char kPostgresPlacesChannel[] = "placerec_places";

// The advisory lock (pg_advisory_xact_lock) that serialises the inserts of every server on one
// map, so that place ids become visible in increasing order.
constexpr int64_t kPostgresInsertLockKey = 0x706c616365726563;  // "placerec"

struct PostgresStoreOptions {
  // How long opening (or re-opening) a connection may wait for the database, seconds.
  int connect_timeout_s = 5;
  // How long an insert may wait for the map's insert lock, and each of its statements may run,
  // milliseconds (PostgreSQL's lock_timeout and statement_timeout within the insert). A server
  // stopped or cut off inside its insert keeps the lock until PostgreSQL ends its session (see
  // idle_in_transaction_session_timeout); the other servers' inserts then fail with an error after
  // this wait instead of blocking their workers, their queries and their shutdown.
  int insert_timeout_ms = 10000;

  bool Check(std::string* error) const;
};

// Whether `db` names a PostgreSQL map: a libpq connection URI, "postgresql://..." or
// "postgres://..." (e.g. postgresql:///placerec?host=/run/placerec-pg for a unix socket).
bool IsPostgresUrl(const std::string& db);

// Connects to the database `url` names and opens the placerec map in it, creating the schema in a
// database that holds no tables. Fails with IoError when the database cannot be reached, holds
// tables but no placerec map, or holds a map of a newer schema version; nothing is changed then.
//
// LoadPlaces and LoadLandmarks each read their own snapshot; LoadLandmarks returns the landmarks
// of the places the last LoadPlaces returned (all of them before any LoadPlaces), so that a map
// opened while other servers insert is consistent. Later places come from the change feed.
StatusOr<std::unique_ptr<LandmarkStore>> OpenPostgresStore(const std::string& url,
                                                           const PostgresStoreOptions& options);

// A place with its landmarks, as the change feed reads them.
struct CommittedPlace {
  Place place;
  std::vector<Landmark> landmarks;
  // Not ok: a row of the place (its own, a landmark's or a sighting's) does not read back whole;
  // the place then holds only its id and no landmarks.
  Status damage;
};

// Another server's view of new places: its own connection, LISTENing on kPostgresPlacesChannel.
// Not thread-safe: one thread uses it. After any IoError the feed is spent: open a new one.
class PostgresChangeFeed {
 public:
  // Connects and LISTENs. IoError when the database cannot be reached (it does not look at the
  // map: a database without one gives no notifications, and FetchAfter fails).
  static StatusOr<std::unique_ptr<PostgresChangeFeed>> Open(const std::string& url,
                                                            const PostgresStoreOptions& options);
  virtual ~PostgresChangeFeed() = default;

  // Waits up to `timeout_ms` for notifications of new places; the number that arrived (0 on
  // timeout). IoError when the connection is lost.
  virtual StatusOr<int> Wait(int timeout_ms) = 0;

  // Reads (in one snapshot) the places with ids above `after`, in increasing id order, at most
  // `max_places` of them, each with its landmarks (checked as LoadLandmarks checks them) and
  // sightings; a damaged place comes marked (CommittedPlace::damage) instead of failing the
  // read. Fewer than `max_places` means there are no more for now.
  virtual StatusOr<std::vector<CommittedPlace>> FetchAfter(PlaceId after, int max_places) = 0;
};

}  // namespace placerec
