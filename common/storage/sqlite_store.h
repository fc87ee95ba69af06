// SQLite implementation of LandmarkStore (DESIGN.md "Architecture"): one file, WAL journal, each
// place committed in one transaction before AddPlace returns. The schema and its versions are in
// schema.h (opening a file written by a newer placerec fails with a message instead of misreading
// it; older files are migrated), the BLOB encodings in blob_codec.h, the digest in checksum.h.
#pragma once

#include <memory>
#include <string>

#include "common/storage/landmark_store.h"
#include "common/storage/schema.h"  // kSqliteSchemaVersion

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

  bool Check(std::string* error) const;
};

// Opens (creating when allowed) the map at `path`; ":memory:" gives a private in-memory map.
// Fails with NotFound for a missing map when options.must_exist is set, and with IoError for a
// file that is not a placerec map or has a newer schema version; such files are left untouched.
StatusOr<std::unique_ptr<LandmarkStore>> OpenSqliteStore(const std::string& path,
                                                         const SqliteStoreOptions& options);

}  // namespace placerec
