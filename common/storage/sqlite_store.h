// SQLite implementation of LandmarkStore (DESIGN.md "Architecture"): one file, WAL journal, each
// place committed in one transaction before AddPlace returns. The schema and its versions are in
// schema.h (opening a file written by a newer placerec fails with a message instead of misreading
// it; older files are migrated), the BLOB encodings in blob_codec.h, the digest in checksum.h.
#pragma once

#include <memory>
#include <string>

#include "common/storage/landmark_store.h"
#include "common/storage/schema.h"  // kSqliteSchemaVersion
#include "common/storage/sqlite_db.h"

namespace placerec {

struct SqliteStoreOptions {
  // PRAGMA synchronous=FULL: a committed place survives power loss, not only a killed process.
  // false gives NORMAL: still safe against a killed process, but the last commits before a power
  // loss may be lost; commits do not wait for fsync.
  bool synchronous_full = true;
  // How long a write waits for another connection's lock (milliseconds).
  int busy_timeout_ms = 5000;
  // Open an existing file only (no creation); for inspection tools.
  bool must_exist = false;
  // Run SQLite's PRAGMA quick_check when an existing map is opened (it reads the whole file
  // once, after one pass over the file in order that brings it into the page cache when it fits
  // in half the available memory): a damaged file is refused with a message saying how to restore
  // or repair it.
  bool quick_check = true;
  // Open for reading only (SQLITE_OPEN_READONLY), for inspection tools: nothing in the file
  // changes (a map of an older schema is read as it is, not upgraded; no journal mode is set),
  // the map must exist, and AddPlace fails.
  bool read_only = false;

  bool Check(std::string* error) const;
};

// Opens (creating when allowed) the map at `path`; ":memory:" gives a private in-memory map.
// A map of an older schema is upgraded in place, unless options.read_only.
// Fails with NotFound for a missing map when options.must_exist is set, and with IoError for a
// file that is not a placerec map, has a newer schema version or (options.quick_check) is damaged;
// such files are left untouched.
StatusOr<std::unique_ptr<LandmarkStore>> OpenSqliteStore(const std::string& path,
                                                         const SqliteStoreOptions& options);

// Opens the map at `path` for reading only (a running server may hold it; nothing in the file
// changes) and reads its schema version into *version: NotFound for a missing file or an empty
// database, IoError for a foreign or newer one (saying what to do when SQLite cannot create the
// -shm file beside a map in WAL mode that it reads the map through).
StatusOr<SqliteConnection> OpenSqliteMapReadOnly(const std::string& path, int busy_timeout_ms,
                                                 int* version);

// What RepairSqliteMap found and did.
struct MapRepairReport {
  // The damage found: SQLite's quick_check complaints, then the first unreadable rows. Empty
  // when the map is whole.
  std::string problems;
  bool rewritten = false;      // the map was rewritten from its readable places
  std::string damaged_copy;    // where the damaged file was moved (when rewritten)
  int64_t places_kept = 0;     // places whose row and every landmark read back whole
  int64_t landmarks_kept = 0;  // their landmarks
  int64_t places_dropped = 0;  // place rows that were damaged, or had a damaged or missing landmark
  // What a rewrite keeps otherwise than stored (no damage: a capture time outside the range, kept
  // as the server uses it); empty when nothing.
  std::string notes;
};

// Repairs the map at `path`: reads it (read-only) place by place with point lookups, so that a
// damaged page costs only the rows on it; a place is kept when its row and all its landmarks
// read back whole. When quick_check or a row found damage, the kept places are written to a new
// map (place and landmark ids are renumbered; robot, sequence and contents stay), the damaged
// file is moved to `path`.damaged (with its -wal) and the new map takes its place. A whole map is
// left as it is. IoError when the file is not a placerec map or its places cannot be listed.
StatusOr<MapRepairReport> RepairSqliteMap(const std::string& path,
                                          const SqliteStoreOptions& options);

}  // namespace placerec
