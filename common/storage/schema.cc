#include "common/storage/schema.h"

#include <charconv>
#include <iterator>
#include <system_error>

#include "common/storage/sqlite_db.h"
#include "common/util/logging.h"

namespace placerec {
namespace {

constexpr char kVersionKey[] = "schema_version";

// Version 0 -> 1: the schema of a new map. `landmarks_place_id` also carries num_descriptors so
// that Counts() sums descriptors from the small index instead of the BLOB-heavy table.
constexpr char kSchemaV1[] = R"sql(
CREATE TABLE meta(
  key TEXT PRIMARY KEY,
  value TEXT);
CREATE TABLE places(
  id INTEGER PRIMARY KEY,
  robot TEXT NOT NULL,
  sequence INTEGER NOT NULL,
  utime INTEGER NOT NULL,
  num_landmarks INTEGER NOT NULL,
  image_width INTEGER NOT NULL,
  UNIQUE(robot, sequence));
CREATE TABLE landmarks(
  id INTEGER PRIMARY KEY,
  place_id INTEGER NOT NULL REFERENCES places(id),
  sift_count INTEGER,
  colour_peaks BLOB,
  segment_class INTEGER,
  box_x INTEGER,
  box_y INTEGER,
  box_w INTEGER,
  box_h INTEGER,
  num_descriptors INTEGER,
  descriptors BLOB,
  keypoints BLOB);
CREATE INDEX landmarks_place_id ON landmarks(place_id, num_descriptors);
)sql";

Status MigrateV0ToV1(sqlite3* db) {
  const int rc = sqlite3_exec(db, kSchemaV1, nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK) return Status::IoError("creating schema v1: " + SqliteMessage(db, rc));
  return Status::Ok();
}

// Version 1 -> 2: every landmark keeps its object class and the classifier's confidence (seed
// Ch. 4). Landmarks of a v1 map stay unclassified: NULL class, confidence 0. Sightings: the
// places that saw a stored landmark again (the seed's scene sets, §5.7 step 5).
constexpr char kSchemaV2[] = R"sql(
ALTER TABLE landmarks ADD COLUMN object_class TEXT;
ALTER TABLE landmarks ADD COLUMN class_confidence REAL NOT NULL DEFAULT 0;
CREATE TABLE sightings(
  place_id INTEGER NOT NULL REFERENCES places(id),
  landmark_id INTEGER NOT NULL REFERENCES landmarks(id),
  PRIMARY KEY(place_id, landmark_id)) WITHOUT ROWID;
)sql";

Status MigrateV1ToV2(sqlite3* db) {
  const int rc = sqlite3_exec(db, kSchemaV2, nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK) return Status::IoError("upgrading to schema v2: " + SqliteMessage(db, rc));
  return Status::Ok();
}

// Version 2 -> 3: a small JPEG per place (Place::thumbnail), in its own table so that scanning
// places never reads picture pages. Places of a v2 map have none.
constexpr char kSchemaV3[] = R"sql(
CREATE TABLE thumbnails(
  place_id INTEGER PRIMARY KEY REFERENCES places(id),
  jpeg BLOB NOT NULL);
)sql";

Status MigrateV2ToV3(sqlite3* db) {
  const int rc = sqlite3_exec(db, kSchemaV3, nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK) return Status::IoError("upgrading to schema v3: " + SqliteMessage(db, rc));
  return Status::Ok();
}

constexpr SchemaMigration kMigrations[] = {&MigrateV0ToV1, &MigrateV1ToV2, &MigrateV2ToV3};
static_assert(std::size(kMigrations) == kSqliteSchemaVersion,
              "one migration step per schema version");

// The tables of the database: how many, and whether `meta` is one of them.
Status ListTables(sqlite3* db, const std::string& path, int* num_tables, bool* has_meta) {
  SqliteStatement tables;
  int rc = SqliteStatement::Prepare(db, "SELECT name FROM sqlite_master WHERE type = 'table'",
                                    false, &tables);
  *num_tables = 0;
  *has_meta = false;
  if (rc == SQLITE_OK) {  // preparing already reads the file: a foreign file fails here
    while ((rc = tables.Step()) == SQLITE_ROW) {
      ++*num_tables;
      if (tables.ColumnText(0) == "meta") *has_meta = true;
    }
  }
  if ((rc & 0xff) == SQLITE_NOTADB) {
    return Status::IoError(path + " is not a SQLite database, so not a placerec map (" +
                           SqliteMessage(db, rc) + ")");
  }
  if (rc != SQLITE_DONE) {
    return Status::IoError("cannot read " + path + ": " + SqliteMessage(db, rc));
  }
  return Status::Ok();
}

Status SetSchemaVersion(sqlite3* db, int version, const std::string& path) {
  SqliteStatement set;
  int rc = SqliteStatement::Prepare(db, "INSERT OR REPLACE INTO meta(key, value) VALUES(?, ?)",
                                    false, &set);
  if (rc == SQLITE_OK) {
    const std::string value = std::to_string(version);
    set.BindText(1, kVersionKey);
    set.BindText(2, value);
    rc = set.Step();
  }
  if (rc != SQLITE_DONE) {
    return Status::IoError("cannot record schema version " + std::to_string(version) + " in " +
                           path + ": " + SqliteMessage(db, rc));
  }
  return Status::Ok();
}

}  // namespace

std::vector<SchemaMigration> CurrentSchemaMigrations() {
  return std::vector<SchemaMigration>(std::begin(kMigrations), std::end(kMigrations));
}

StatusOr<int> ReadSchemaVersion(sqlite3* db, const std::string& path) {
  int num_tables = 0;
  bool has_meta = false;
  PLACEREC_RETURN_IF_ERROR(ListTables(db, path, &num_tables, &has_meta));
  if (num_tables == 0) return 0;
  if (!has_meta) {
    return Status::IoError(
        path + " is not a placerec map: a SQLite database with tables but no meta table");
  }

  SqliteStatement version;
  int rc = SqliteStatement::Prepare(db, "SELECT value FROM meta WHERE key = ?", false, &version);
  if (rc == SQLITE_OK) {
    version.BindText(1, kVersionKey);
    rc = version.Step();
  }
  if (rc == SQLITE_DONE) {
    return Status::IoError(path + " is not a placerec map: its meta table has no schema_version");
  }
  if (rc != SQLITE_ROW) {
    return Status::IoError("cannot read the schema version of " + path + ": " +
                           SqliteMessage(db, rc));
  }
  const std::string text = version.ColumnText(0);
  int value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size() || value < 1) {
    return Status::IoError(path + " is not a placerec map: schema_version is '" + text + "'");
  }
  return value;
}

Status NewerSchemaVersionError(const std::string& path, int version, int supported) {
  return Status::IoError(path + " has schema version " + std::to_string(version) +
                         " but this build of placerec reads versions up to " +
                         std::to_string(supported) + "; upgrade placerec");
}

Status MigrateSchemaToCurrent(sqlite3* db, const std::string& path) {
  return MigrateSchema(db, path, CurrentSchemaMigrations());
}

Status MigrateSchema(sqlite3* db, const std::string& path,
                     const std::vector<SchemaMigration>& steps) {
  const int target = static_cast<int>(steps.size());
  SqliteTransaction transaction(db);
  int rc = transaction.Begin(/*immediate=*/true);
  if (rc != SQLITE_OK) {
    return Status::IoError("cannot lock " + path +
                           " to write its schema: " + SqliteMessage(db, rc));
  }
  // Read again under the write lock: another process may have created the map meanwhile.
  StatusOr<int> from = ReadSchemaVersion(db, path);
  if (!from.ok()) return from.status();
  if (*from > target) return NewerSchemaVersionError(path, *from, target);
  if (*from == target) return Status::Ok();
  for (int version = *from; version < target; ++version) {
    const Status step = steps[static_cast<size_t>(version)](db);
    if (!step.ok()) return Status::IoError(path + ": " + step.message());
    PLACEREC_RETURN_IF_ERROR(SetSchemaVersion(db, version + 1, path));
  }
  rc = transaction.Commit();
  if (rc != SQLITE_OK) {
    return Status::IoError("cannot commit the schema of " + path + ": " + SqliteMessage(db, rc));
  }
  LOG(INFO) << (*from == 0 ? "created placerec map " : "upgraded placerec map ") << path
            << " to schema version " << target;
  return Status::Ok();
}

}  // namespace placerec
