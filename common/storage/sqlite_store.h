// SQLite implementation of LandmarkStore: one file, WAL journal, each place committed in one
// transaction. The schema carries a version (table `meta`, key `schema_version`); opening a file
// written by a newer placerec fails with a message instead of misreading it.
#pragma once

#include <memory>
#include <string>

#include "common/storage/landmark_store.h"

namespace placerec {

// Version of the schema this build writes.
constexpr int kSqliteSchemaVersion = 1;

struct SqliteStoreOptions {
  // PRAGMA synchronous=FULL: a committed place survives power loss, not only a killed process.
  bool synchronous_full = true;
  // How long a write waits for another connection's lock (milliseconds).
  int busy_timeout_ms = 5000;
  // Open an existing file only (no creation); for inspection tools.
  bool must_exist = false;

  bool Check(std::string* error) const;
};

// Opens (creating when allowed) the map at `path`; ":memory:" gives a private in-memory map.
StatusOr<std::unique_ptr<LandmarkStore>> OpenSqliteStore(const std::string& path,
                                                         const SqliteStoreOptions& options);

}  // namespace placerec
