// Test helpers shared by the storage tests: temporary map files and direct SQL on them, to forge
// foreign, older, newer or damaged maps behind the store's back; landmarks built from explicit
// values only, and their comparison after a round trip. Tests only.
#pragma once

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <string>

#include "common/recognition/types.h"

namespace placerec {
namespace testing_storage {

// A map file in the test's temporary directory, removed (with its WAL files) before and after.
// The process id keeps concurrent runs (several build trees, ctest -j) apart.
class TempMap {
 public:
  explicit TempMap(const std::string& name)
      : path_(::testing::TempDir() + "/placerec_storage_" + name + "_" + std::to_string(getpid()) +
              ".db") {
    Remove();
  }
  ~TempMap() { Remove(); }
  const std::string& path() const { return path_; }

 private:
  void Remove() const {
    for (const char* suffix : {"", "-wal", "-shm", "-journal", ".index"}) {
      std::remove((path_ + suffix).c_str());
    }
  }
  std::string path_;
};

// Runs constant SQL on a map file directly, to forge foreign, newer or damaged files.
inline void ExecSql(const std::string& path, const char* sql) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  char* error = nullptr;
  const int rc = sqlite3_exec(db, sql, nullptr, nullptr, &error);
  EXPECT_EQ(rc, SQLITE_OK) << (error != nullptr ? error : "");
  sqlite3_free(error);
  sqlite3_close(db);
}

// Turns a map of the current schema back into one of schema v1, as an old placerec wrote it:
// what the v2 and v3 steps added is removed again (classes, sightings, thumbnails).
inline void DowngradeMapToSchemaV1(const std::string& path) {
  ExecSql(path,
          "DROP TABLE thumbnails; DROP TABLE sightings; "
          "ALTER TABLE landmarks DROP COLUMN object_class; "
          "ALTER TABLE landmarks DROP COLUMN class_confidence; "
          "UPDATE meta SET value = '1' WHERE key = 'schema_version'; VACUUM;");
}

// The first column of the first row of a constant query, as text.
inline std::string QuerySql(const std::string& path, const char* sql) {
  sqlite3* db = nullptr;
  std::string value;
  if (sqlite3_open(path.c_str(), &db) == SQLITE_OK) {
    sqlite3_stmt* stmt = nullptr;
    if (sqlite3_prepare_v2(db, sql, -1, &stmt, nullptr) == SQLITE_OK &&
        sqlite3_step(stmt) == SQLITE_ROW) {
      value = reinterpret_cast<const char*>(sqlite3_column_text(stmt, 0));
    }
    sqlite3_finalize(stmt);
  }
  sqlite3_close(db);
  return value;
}

// A landmark made of explicit values only (no random numbers): `index` + 1 colour peaks,
// `index` + 2 descriptors with their keypoints, a box that may start at negative coordinates.
inline Landmark ExplicitLandmark(int index) {
  Landmark landmark;
  landmark.sift_count = 10 + index;
  landmark.colour.peaks.assign(static_cast<size_t>(index + 1),
                               0.25f - 0.5f * static_cast<float>(index));
  landmark.segment_class = index == 0 ? SegmentClass::kStructured : SegmentClass::kWater;
  landmark.box = cv::Rect(-3 + index, 7, 40, 25 + index);
  const int rows = 2 + index;
  landmark.descriptors.create(rows, 128, CV_8U);
  for (int row = 0; row < rows; ++row) {
    for (int col = 0; col < 128; ++col) {
      landmark.descriptors.at<uint8_t>(row, col) = static_cast<uint8_t>(row * 37 + col * 5 + index);
    }
    landmark.keypoints.emplace_back(
        10.5f * static_cast<float>(row), 3.25f + static_cast<float>(index),
        2.0f + static_cast<float>(row), -45.0f * static_cast<float>(row));
  }
  return landmark;
}

// Expects `actual` to hold what a store keeps of `expected`: every field, and of the keypoints
// x, y, size and angle.
inline void ExpectSameLandmark(const Landmark& expected, const Landmark& actual) {
  EXPECT_EQ(actual.id, expected.id);
  EXPECT_EQ(actual.place, expected.place);
  EXPECT_EQ(actual.sift_count, expected.sift_count);
  EXPECT_EQ(actual.colour.peaks, expected.colour.peaks);
  EXPECT_EQ(actual.box, expected.box);
  EXPECT_EQ(actual.segment_class, expected.segment_class);
  EXPECT_EQ(actual.object_class, expected.object_class);
  EXPECT_EQ(actual.class_confidence, expected.class_confidence);
  ASSERT_EQ(actual.descriptors.type(), CV_8U);
  ASSERT_EQ(actual.descriptors.cols, 128);
  ASSERT_EQ(actual.descriptors.rows, expected.descriptors.rows);
  if (expected.descriptors.rows > 0) {
    EXPECT_EQ(cv::countNonZero(actual.descriptors != expected.descriptors), 0);
  }
  ASSERT_EQ(actual.keypoints.size(), expected.keypoints.size());
  for (size_t i = 0; i < expected.keypoints.size(); ++i) {
    EXPECT_EQ(actual.keypoints[i].pt.x, expected.keypoints[i].pt.x) << i;
    EXPECT_EQ(actual.keypoints[i].pt.y, expected.keypoints[i].pt.y) << i;
    EXPECT_EQ(actual.keypoints[i].size, expected.keypoints[i].size) << i;
    EXPECT_EQ(actual.keypoints[i].angle, expected.keypoints[i].angle) << i;
  }
}

}  // namespace testing_storage
}  // namespace placerec
