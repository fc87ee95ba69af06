// SQLite implementation of LandmarkStore (DESIGN.md "Architecture"): one file, WAL journal, each
// place committed in one transaction before AddPlace returns. The schema carries a version (table
// `meta`, key `schema_version`); opening a file written by a newer placerec fails with a message
// instead of misreading it, and older files are migrated one version step at a time.
//
// Schema v1: places(id, robot, sequence, utime, num_landmarks), UNIQUE(robot, sequence);
// landmarks(id, place_id, sift_count, colour_peaks, segment_class, box_x, box_y, box_w, box_h,
// num_descriptors, descriptors, keypoints). BLOBs: colour_peaks float32 LE per peak, descriptors
// num_descriptors * 128 bytes (CV_8U rows), keypoints float32 LE x, y, size, angle per
// descriptor. Ids are SQLite rowids: they start at 1 and increase.
#pragma once

#include <memory>
#include <string>

#include "common/storage/landmark_store.h"

namespace placerec {

// Version of the schema this build writes.
constexpr int kSqliteSchemaVersion = 1;

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
