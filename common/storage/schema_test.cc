#include "common/storage/schema.h"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <memory>
#include <string>
#include <vector>

#include "common/storage/sqlite_db.h"
#include "common/storage/sqlite_store.h"
#include "common/storage/storage_testing.h"

namespace placerec {
namespace {

constexpr char kPath[] = "test.db";  // only for messages

bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// An empty in-memory database.
SqliteConnection NewDatabase() {
  sqlite3* raw = nullptr;
  EXPECT_EQ(sqlite3_open(":memory:", &raw), SQLITE_OK);
  return SqliteConnection(raw);
}

void Exec(sqlite3* db, const char* sql) { ASSERT_TRUE(SqliteExec(db, sql, kPath).ok()) << sql; }

// The first column of the first row of `sql`, as text ("" when there is none).
std::string Query(sqlite3* db, const char* sql) {
  SqliteStatement statement;
  if (SqliteStatement::Prepare(db, sql, false, &statement) != SQLITE_OK) return "";
  return statement.Step() == SQLITE_ROW ? statement.ColumnText(0) : "";
}

int VersionOf(sqlite3* db) {
  StatusOr<int> version = ReadSchemaVersion(db, kPath);
  EXPECT_TRUE(version.ok()) << version.status().ToString();
  return version.ok() ? *version : -1;
}

// A made-up step to a version 2: a new column, and a count of the runs.
int add_column_runs = 0;
Status AddColumn(sqlite3* db) {
  ++add_column_runs;
  return SqliteExec(db, "ALTER TABLE places ADD COLUMN note TEXT", kPath);
}

// A step that fails half-way, after changing the file.
Status CreateThenFail(sqlite3* db) {
  PLACEREC_RETURN_IF_ERROR(SqliteExec(db, "CREATE TABLE half(x)", kPath));
  return Status::IoError("step failed on purpose");
}

TEST(SchemaTest, NewDatabaseIsVersionZeroAndMigratesToCurrent) {
  SqliteConnection db = NewDatabase();
  EXPECT_EQ(VersionOf(db.get()), 0);
  EXPECT_EQ(CurrentSchemaMigrations().size(), static_cast<size_t>(kSqliteSchemaVersion));
  ASSERT_TRUE(MigrateSchemaToCurrent(db.get(), kPath).ok());
  EXPECT_EQ(VersionOf(db.get()), kSqliteSchemaVersion);
  EXPECT_EQ(Query(db.get(),
                  "SELECT group_concat(name, ',') FROM (SELECT name FROM sqlite_master "
                  "ORDER BY name)"),
            "landmarks,landmarks_place_id,meta,places,sightings,sqlite_autoindex_meta_1,"
            "sqlite_autoindex_places_1,thumbnails");
  // Migrating a current map changes nothing.
  ASSERT_TRUE(MigrateSchemaToCurrent(db.get(), kPath).ok());
  EXPECT_EQ(Query(db.get(), "SELECT COUNT(*) FROM meta"), "1");
}

TEST(SchemaTest, OlderMapIsMigratedOneStepAtATimeKeepingItsData) {
  SqliteConnection db = NewDatabase();
  ASSERT_TRUE(MigrateSchemaToCurrent(db.get(), kPath).ok());
  Exec(db.get(),
       "INSERT INTO places(robot, sequence, utime, num_landmarks, image_width) "
       "VALUES('r', 1, 2, 0, 640)");
  std::vector<SchemaMigration> steps = CurrentSchemaMigrations();
  steps.push_back(&AddColumn);

  add_column_runs = 0;
  ASSERT_TRUE(MigrateSchema(db.get(), kPath, steps).ok());
  EXPECT_EQ(add_column_runs, 1);
  EXPECT_EQ(VersionOf(db.get()), kSqliteSchemaVersion + 1);
  EXPECT_EQ(Query(db.get(), "SELECT robot || '/' || COALESCE(note, 'none') FROM places"), "r/none");
  // Now current for these steps: nothing runs again.
  ASSERT_TRUE(MigrateSchema(db.get(), kPath, steps).ok());
  EXPECT_EQ(add_column_runs, 1);

  // An empty database goes through every step.
  SqliteConnection empty = NewDatabase();
  ASSERT_TRUE(MigrateSchema(empty.get(), kPath, steps).ok());
  EXPECT_EQ(add_column_runs, 2);
  EXPECT_EQ(VersionOf(empty.get()), kSqliteSchemaVersion + 1);
}

TEST(SchemaTest, FailedStepChangesNothing) {
  SqliteConnection db = NewDatabase();
  ASSERT_TRUE(MigrateSchemaToCurrent(db.get(), kPath).ok());
  std::vector<SchemaMigration> steps = CurrentSchemaMigrations();
  steps.push_back(&AddColumn);
  steps.push_back(&CreateThenFail);
  const Status status = MigrateSchema(db.get(), kPath, steps);
  EXPECT_EQ(status.code(), StatusCode::kIoError);
  EXPECT_EQ(status.message(), "test.db: step failed on purpose");
  EXPECT_EQ(VersionOf(db.get()), kSqliteSchemaVersion);
  EXPECT_EQ(Query(db.get(), "SELECT COUNT(*) FROM sqlite_master WHERE name = 'half'"), "0");
  EXPECT_EQ(Query(db.get(), "SELECT COUNT(*) FROM pragma_table_info('places') WHERE name = 'note'"),
            "0");
  EXPECT_NE(sqlite3_get_autocommit(db.get()), 0);  // and no transaction is left open
}

TEST(SchemaTest, NewerMapIsRefusedAndLeftAlone) {
  SqliteConnection db = NewDatabase();
  ASSERT_TRUE(MigrateSchemaToCurrent(db.get(), kPath).ok());
  Exec(db.get(), "UPDATE meta SET value = '4' WHERE key = 'schema_version'");
  const Status status = MigrateSchemaToCurrent(db.get(), kPath);
  EXPECT_EQ(status.code(), StatusCode::kIoError);
  EXPECT_EQ(status.message(),
            "test.db has schema version 4 but this build of placerec reads versions up to 3; "
            "upgrade placerec");
  EXPECT_EQ(VersionOf(db.get()), 4);
}

TEST(SchemaTest, ReadVersionRefusesWhatIsNotAPlacerecMap) {
  const struct {
    const char* sql;
    const char* message;
  } cases[] = {
      {"CREATE TABLE things(id)", "a SQLite database with tables but no meta table"},
      {"CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT)",
       "its meta table has no schema_version"},
      {"CREATE TABLE meta(key, value); INSERT INTO meta VALUES('schema_version', 'abc')",
       "schema_version is 'abc'"},
      {"CREATE TABLE meta(key, value); INSERT INTO meta VALUES('schema_version', '1x')",
       "schema_version is '1x'"},
      {"CREATE TABLE meta(key, value); INSERT INTO meta VALUES('schema_version', '0')",
       "schema_version is '0'"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.sql);
    SqliteConnection db = NewDatabase();
    Exec(db.get(), c.sql);
    const StatusOr<int> version = ReadSchemaVersion(db.get(), kPath);
    ASSERT_FALSE(version.ok());
    EXPECT_EQ(version.status().code(), StatusCode::kIoError);
    EXPECT_TRUE(Contains(version.status().message(), "test.db is not a placerec map: "))
        << version.status().message();
    EXPECT_TRUE(Contains(version.status().message(), c.message)) << version.status().message();
  }
}

// A version 1 map as an earlier build wrote it, laid down by hand with the v1 DDL and BLOB
// encodings (schema.h, blob_codec.h), opens, is migrated to the current version and reads back
// as documented: its landmarks without a class.
TEST(SchemaTest, HandWrittenVersionOneMapOpensAndReads) {
  testing_storage::TempMap map("schema_v1");
  testing_storage::ExecSql(
      map.path(),
      "CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT);"
      "CREATE TABLE places(id INTEGER PRIMARY KEY, robot TEXT NOT NULL, sequence INTEGER NOT "
      "NULL, utime INTEGER NOT NULL, num_landmarks INTEGER NOT NULL, image_width INTEGER NOT "
      "NULL, UNIQUE(robot, sequence));"
      "CREATE TABLE landmarks(id INTEGER PRIMARY KEY, place_id INTEGER NOT NULL REFERENCES "
      "places(id), sift_count INTEGER, colour_peaks BLOB, segment_class INTEGER, box_x "
      "INTEGER, box_y INTEGER, box_w INTEGER, box_h INTEGER, num_descriptors INTEGER, "
      "descriptors BLOB, keypoints BLOB);"
      "CREATE INDEX landmarks_place_id ON landmarks(place_id, num_descriptors);"
      "INSERT INTO meta VALUES('schema_version', '1');"
      "INSERT INTO places VALUES(1, 'r1', 5, 1700000000000000, 1, 640);"
      "INSERT INTO landmarks VALUES(1, 1, 9, X'0000003F', 4, -2, 3, 40, 30, 1, zeroblob(128),"
      " X'0000803F000000C00000803E0000B442');");
  StatusOr<std::unique_ptr<LandmarkStore>> opened =
      OpenSqliteStore(map.path(), SqliteStoreOptions());
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  std::unique_ptr<LandmarkStore> store = std::move(opened).value();

  std::vector<Place> places;
  ASSERT_TRUE(store->LoadPlaces([&places](const Place& place) { places.push_back(place); }).ok());
  ASSERT_EQ(places.size(), 1u);
  EXPECT_EQ(places[0].id, PlaceId(1));
  EXPECT_EQ(places[0].robot, "r1");
  EXPECT_EQ(places[0].sequence, 5);
  EXPECT_EQ(places[0].utime, 1700000000000000);
  EXPECT_EQ(places[0].num_landmarks, 1);
  EXPECT_EQ(places[0].image_width, 640);

  std::vector<Landmark> landmarks;
  ASSERT_TRUE(
      store->LoadLandmarks([&landmarks](Landmark&& l) { landmarks.push_back(std::move(l)); }).ok());
  Landmark expected;
  expected.id = LandmarkId(1);
  expected.place = PlaceId(1);
  expected.sift_count = 9;
  expected.colour.peaks = {0.5f};
  expected.segment_class = SegmentClass::kWater;
  expected.box = cv::Rect(-2, 3, 40, 30);
  expected.descriptors = cv::Mat::zeros(1, 128, CV_8U);
  expected.keypoints.emplace_back(1.0f, -2.0f, 0.25f, 90.0f);
  ASSERT_EQ(landmarks.size(), 1u);
  testing_storage::ExpectSameLandmark(expected, landmarks[0]);

  // It is a current map now, keeps its checksum (a map without classes hashes as under v1) and
  // takes new places, classified landmarks too, after the old ones.
  const StatusOr<uint64_t> checksum = store->Checksum();
  ASSERT_TRUE(checksum.ok());
  // FNV-1a 64 of the documented serialization (checksum.h), computed by hand.
  EXPECT_EQ(*checksum, 0x1dd3c408b7a94dbau) << std::hex << *checksum;
  // The old place has no thumbnail (schema v3); a new one keeps its own.
  EXPECT_TRUE(store->LoadThumbnail(PlaceId(1))->empty());
  Place place;
  place.robot = "r1";
  place.sequence = 6;
  place.thumbnail = {0xff, 0xd8, 0x01, 0x02};
  std::vector<Landmark> classified(1);
  classified[0].object_class = "sign";
  classified[0].class_confidence = 0.625f;
  ASSERT_TRUE(store->AddPlace(&place, &classified).ok());
  EXPECT_EQ(place.id, PlaceId(2));
  EXPECT_EQ(*store->LoadThumbnail(PlaceId(2)), place.thumbnail);
  store.reset();
  EXPECT_EQ(
      testing_storage::QuerySql(map.path(), "SELECT value FROM meta WHERE key = 'schema_version'"),
      std::to_string(kSqliteSchemaVersion));
  EXPECT_EQ(testing_storage::QuerySql(map.path(),
                                      "SELECT object_class || ' ' || class_confidence FROM "
                                      "landmarks WHERE id = 2"),
            "sign 0.625");
  EXPECT_EQ(testing_storage::QuerySql(
                map.path(),
                "SELECT COUNT(*) FROM landmarks WHERE id = 1 AND object_class IS NULL "
                "AND class_confidence = 0"),
            "1");
}

}  // namespace
}  // namespace placerec
