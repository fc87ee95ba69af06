// The SQLite schema of a landmark map and its versions. The version lives in table `meta`, key
// `schema_version`; a file written by a newer placerec is refused instead of misread, and older
// files are migrated one version step at a time, all steps in one transaction.
//
// Schema v1: places(id, robot, sequence, utime, num_landmarks, image_width),
// UNIQUE(robot, sequence); landmarks(id, place_id, sift_count, colour_peaks, segment_class, box_x,
// box_y, box_w, box_h, num_descriptors, descriptors, keypoints), indexed on (place_id,
// num_descriptors). The BLOB columns hold the encodings of blob_codec.h. Ids are SQLite rowids:
// they start at 1 and increase.
//
// Schema v2 adds landmarks(object_class TEXT, NULL when unclassified; class_confidence REAL in
// [0, 1], 0 when unclassified): the object classes of seed Ch. 4; and sightings(place_id,
// landmark_id), the stored landmarks a later place saw again (Place::seen_landmarks, the seed's
// scene sets of §5.7 step 5). A v1 map is migrated by adding the two columns and the empty table;
// its landmarks stay unclassified.
//
// Schema v3 adds thumbnails(place_id PRIMARY KEY, jpeg BLOB): a small JPEG of each place's frame
// (Place::thumbnail) for alarms, matches, tools and scene-change detection (seed §7.2.4). A v2 map
// is migrated by adding the empty table: its places have no thumbnails.
#pragma once

#include <string>
#include <vector>

#include "common/util/status.h"

struct sqlite3;

namespace placerec {

// Version of the schema this build writes.
constexpr int kSqliteSchemaVersion = 3;

// One migration step: turns a map of version v into one of version v + 1. It runs inside the
// driver's transaction and does not touch meta.schema_version.
using SchemaMigration = Status (*)(sqlite3* db);

// This build's steps: element v turns version v into v + 1 (version 0 is an empty file), so
// there are kSqliteSchemaVersion of them. A new version appends its step and bumps the constant.
std::vector<SchemaMigration> CurrentSchemaMigrations();

// The schema version of the open database: 0 when it holds no tables at all (a new file), an
// IoError when it is not SQLite or not a placerec map. `path` is for messages only.
StatusOr<int> ReadSchemaVersion(sqlite3* db, const std::string& path);

// The IoError for a map of schema `version`, newer than the `supported` one of this build.
Status NewerSchemaVersionError(const std::string& path, int version,
                               int supported = kSqliteSchemaVersion);

// Brings the map to kSqliteSchemaVersion with CurrentSchemaMigrations().
Status MigrateSchemaToCurrent(sqlite3* db, const std::string& path);

// Brings the map to version steps.size() in one immediate (write-locking) transaction: reads the
// version again under the lock (another process may have migrated it meanwhile), runs the missing
// steps and records the new version after each. On any error nothing is changed; a newer map is
// refused with NewerSchemaVersionError.
Status MigrateSchema(sqlite3* db, const std::string& path,
                     const std::vector<SchemaMigration>& steps);

}  // namespace placerec
