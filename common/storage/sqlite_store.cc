#include "common/storage/sqlite_store.h"

#include <sqlite3.h>

#include <charconv>
#include <climits>
#include <cstring>
#include <filesystem>
#include <iterator>
#include <limits>
#include <mutex>
#include <system_error>
#include <utility>
#include <vector>

#include "common/features/features.h"
#include "common/util/logging.h"

namespace placerec {
namespace {

static_assert(sizeof(float) == 4 && std::numeric_limits<float>::is_iec559,
              "the BLOB formats store IEEE-754 float32");

// Bytes of one stored keypoint: float32 x, y, size, angle, little-endian.
constexpr size_t kKeypointBytes = 16;
// Bytes of one stored colour peak: float32, little-endian.
constexpr size_t kPeakBytes = 4;

// ---------------------------------------------------------------------------------------------
// Little-endian float32 encoding of the BLOB columns.

void AppendFloat(float value, std::vector<uint8_t>* out) {
  uint32_t bits = 0;
  std::memcpy(&bits, &value, sizeof(bits));
  for (int shift = 0; shift < 32; shift += 8) out->push_back(static_cast<uint8_t>(bits >> shift));
}

float ReadFloat(const uint8_t* bytes) {
  const uint32_t bits = static_cast<uint32_t>(bytes[0]) | static_cast<uint32_t>(bytes[1]) << 8 |
                        static_cast<uint32_t>(bytes[2]) << 16 |
                        static_cast<uint32_t>(bytes[3]) << 24;
  float value = 0;
  std::memcpy(&value, &bits, sizeof(value));
  return value;
}

void EncodePeaks(const ColourSignature& colour, std::vector<uint8_t>* out) {
  out->clear();
  for (float peak : colour.peaks) AppendFloat(peak, out);
}

void EncodeKeypoints(const std::vector<cv::KeyPoint>& keypoints, std::vector<uint8_t>* out) {
  out->clear();
  for (const cv::KeyPoint& keypoint : keypoints) {
    AppendFloat(keypoint.pt.x, out);
    AppendFloat(keypoint.pt.y, out);
    AppendFloat(keypoint.size, out);
    AppendFloat(keypoint.angle, out);
  }
}

// ---------------------------------------------------------------------------------------------
// FNV-1a 64 over the canonical serialization used by Checksum().

class Fnv1a64 {
 public:
  void Bytes(const uint8_t* data, size_t size) {
    for (size_t i = 0; i < size; ++i) {
      hash_ ^= data[i];
      hash_ *= 1099511628211ULL;
    }
  }
  void Byte(uint8_t value) { Bytes(&value, 1); }
  // Every integer enters as 8 bytes, little-endian, whatever its C++ type.
  void Int(int64_t value) {
    uint8_t bytes[8];
    for (int i = 0; i < 8; ++i) {
      bytes[i] = static_cast<uint8_t>(static_cast<uint64_t>(value) >> (8 * i));
    }
    Bytes(bytes, sizeof(bytes));
  }
  uint64_t digest() const { return hash_; }

 private:
  uint64_t hash_ = 14695981039346656037ULL;
};

// ---------------------------------------------------------------------------------------------
// RAII wrappers around the sqlite3 C API.

struct ConnectionCloser {
  // close_v2 also copes with statements that are still alive (it defers the close).
  void operator()(sqlite3* db) const { sqlite3_close_v2(db); }
};
using Connection = std::unique_ptr<sqlite3, ConnectionCloser>;

std::string SqliteMessage(sqlite3* db, int rc) {
  std::string message = db != nullptr ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
  return message + " (sqlite code " + std::to_string(rc) + ")";
}

// A prepared statement. Values are always bound, never formatted into the SQL. A failed bind is
// remembered and reported by the next Step().
class Statement {
 public:
  Statement() = default;
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  Statement(Statement&& other) noexcept
      : stmt_(std::exchange(other.stmt_, nullptr)), bind_rc_(other.bind_rc_) {}
  Statement& operator=(Statement&& other) noexcept {
    if (this != &other) {
      sqlite3_finalize(stmt_);
      stmt_ = std::exchange(other.stmt_, nullptr);
      bind_rc_ = other.bind_rc_;
    }
    return *this;
  }
  ~Statement() { sqlite3_finalize(stmt_); }

  // Compiles one SQL statement; `persistent` hints that it is kept and reused.
  static int Prepare(sqlite3* db, const char* sql, bool persistent, Statement* out) {
    sqlite3_stmt* stmt = nullptr;
    const int rc =
        sqlite3_prepare_v3(db, sql, -1, persistent ? SQLITE_PREPARE_PERSISTENT : 0, &stmt, nullptr);
    *out = Statement();
    out->stmt_ = stmt;
    return rc;
  }

  // Parameters are numbered from 1. Bound text and blobs must outlive the next Step().
  void BindInt(int index, int64_t value) { Note(sqlite3_bind_int64(stmt_, index, value)); }
  void BindText(int index, const std::string& text) { BindText(index, text.data(), text.size()); }
  void BindText(int index, const char* text) { BindText(index, text, std::strlen(text)); }
  // SQLite keeps a pointer to bound text until the step: a temporary would dangle.
  void BindText(int index, std::string&& text) = delete;
  void BindBlob(int index, const void* data, size_t size) {
    // A zero-length blob, not NULL, when there is nothing to store.
    Note(size == 0 ? sqlite3_bind_zeroblob(stmt_, index, 0)
                   : sqlite3_bind_blob64(stmt_, index, data, size, SQLITE_STATIC));
  }

  // SQLITE_ROW when a row is ready, SQLITE_DONE at the end, or an error code.
  int Step() { return bind_rc_ != SQLITE_OK ? bind_rc_ : sqlite3_step(stmt_); }

  // Makes a kept statement ready for the next use and drops references to bound buffers.
  void Reset() {
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
    bind_rc_ = SQLITE_OK;
  }

  int ColumnType(int column) const { return sqlite3_column_type(stmt_, column); }
  int64_t ColumnInt(int column) const { return sqlite3_column_int64(stmt_, column); }
  std::string ColumnText(int column) const {
    const unsigned char* text = sqlite3_column_text(stmt_, column);
    const int size = sqlite3_column_bytes(stmt_, column);
    return text == nullptr ? std::string() : std::string(reinterpret_cast<const char*>(text), size);
  }
  // Valid until the next Step() or Reset(); {nullptr, 0} for NULL and empty blobs.
  std::pair<const uint8_t*, size_t> ColumnBlob(int column) const {
    const void* data = sqlite3_column_blob(stmt_, column);
    const int size = sqlite3_column_bytes(stmt_, column);
    return {static_cast<const uint8_t*>(data), static_cast<size_t>(size)};
  }

 private:
  void BindText(int index, const char* text, size_t size) {
    Note(sqlite3_bind_text64(stmt_, index, text, size, SQLITE_STATIC, SQLITE_UTF8));
  }
  void Note(int rc) {
    if (bind_rc_ == SQLITE_OK) bind_rc_ = rc;
  }

  sqlite3_stmt* stmt_ = nullptr;
  int bind_rc_ = SQLITE_OK;
};

// Resets a kept statement when the scope ends, whichever way it ends.
class ScopedReset {
 public:
  explicit ScopedReset(Statement* statement) : statement_(statement) {}
  ScopedReset(const ScopedReset&) = delete;
  ScopedReset& operator=(const ScopedReset&) = delete;
  ~ScopedReset() { statement_->Reset(); }

 private:
  Statement* statement_;
};

// A transaction that rolls back unless Commit() succeeded. IMMEDIATE takes the write lock at
// BEGIN, so a writer never fails half-way on a lock held by another connection.
class Transaction {
 public:
  explicit Transaction(sqlite3* db) : db_(db) {}
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;
  ~Transaction() {
    // SQLite may already have rolled back by itself after an I/O error.
    if (active_ && sqlite3_get_autocommit(db_) == 0) {
      const int rc = sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
      LOG_IF(ERROR, rc != SQLITE_OK) << "sqlite rollback failed: " << SqliteMessage(db_, rc);
    }
  }

  int Begin(bool immediate) {
    const int rc =
        sqlite3_exec(db_, immediate ? "BEGIN IMMEDIATE" : "BEGIN", nullptr, nullptr, nullptr);
    active_ = rc == SQLITE_OK;
    return rc;
  }
  int Commit() {
    const int rc = sqlite3_exec(db_, "COMMIT", nullptr, nullptr, nullptr);
    if (rc == SQLITE_OK) active_ = false;
    return rc;
  }

 private:
  sqlite3* db_;
  bool active_ = false;
};

// ---------------------------------------------------------------------------------------------
// Schema and its versions.

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

// kMigrations[v] turns a version-v map into a version-(v + 1) map; version 0 is an empty file.
// A new version appends its step here and bumps kSqliteSchemaVersion; the driver sets
// meta.schema_version after each step, all in one transaction.
using MigrationStep = Status (*)(sqlite3* db);
constexpr MigrationStep kMigrations[] = {&MigrateV0ToV1};
static_assert(std::size(kMigrations) == kSqliteSchemaVersion,
              "one migration step per schema version");

// The schema version of the open database: 0 when it holds no tables at all (a new file), an
// error when it is not SQLite or not a placerec map.
StatusOr<int> ReadSchemaVersion(sqlite3* db, const std::string& path) {
  Statement tables;
  int rc =
      Statement::Prepare(db, "SELECT name FROM sqlite_master WHERE type = 'table'", false, &tables);
  int num_tables = 0;
  bool has_meta = false;
  if (rc == SQLITE_OK) {  // preparing already reads the file: a foreign file fails here
    while ((rc = tables.Step()) == SQLITE_ROW) {
      ++num_tables;
      if (tables.ColumnText(0) == "meta") has_meta = true;
    }
  }
  if ((rc & 0xff) == SQLITE_NOTADB) {
    return Status::IoError(path + " is not a SQLite database, so not a placerec map (" +
                           SqliteMessage(db, rc) + ")");
  }
  if (rc != SQLITE_DONE) {
    return Status::IoError("cannot read " + path + ": " + SqliteMessage(db, rc));
  }
  if (num_tables == 0) return 0;
  if (!has_meta) {
    return Status::IoError(
        path + " is not a placerec map: a SQLite database with tables but no meta table");
  }

  Statement version;
  rc = Statement::Prepare(db, "SELECT value FROM meta WHERE key = ?", false, &version);
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

Status NewerVersionError(const std::string& path, int version) {
  return Status::IoError(path + " has schema version " + std::to_string(version) +
                         " but this build of placerec reads versions up to " +
                         std::to_string(kSqliteSchemaVersion) + "; upgrade placerec");
}

Status SetSchemaVersion(sqlite3* db, int version, const std::string& path) {
  Statement set;
  int rc =
      Statement::Prepare(db, "INSERT OR REPLACE INTO meta(key, value) VALUES(?, ?)", false, &set);
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

// Brings the map to kSqliteSchemaVersion in one transaction (creating it when empty).
Status MigrateToCurrent(sqlite3* db, const std::string& path) {
  Transaction transaction(db);
  int rc = transaction.Begin(/*immediate=*/true);
  if (rc != SQLITE_OK) {
    return Status::IoError("cannot lock " + path +
                           " to write its schema: " + SqliteMessage(db, rc));
  }
  // Read again under the write lock: another process may have created the map meanwhile.
  StatusOr<int> from = ReadSchemaVersion(db, path);
  if (!from.ok()) return from.status();
  if (*from > kSqliteSchemaVersion) return NewerVersionError(path, *from);
  if (*from == kSqliteSchemaVersion) return Status::Ok();
  for (int version = *from; version < kSqliteSchemaVersion; ++version) {
    const Status step = kMigrations[version](db);
    if (!step.ok()) return Status::IoError(path + ": " + step.message());
    PLACEREC_RETURN_IF_ERROR(SetSchemaVersion(db, version + 1, path));
  }
  rc = transaction.Commit();
  if (rc != SQLITE_OK) {
    return Status::IoError("cannot commit the schema of " + path + ": " + SqliteMessage(db, rc));
  }
  LOG(INFO) << (*from == 0 ? "created placerec map " : "upgraded placerec map ") << path
            << " to schema version " << kSqliteSchemaVersion;
  return Status::Ok();
}

Status Exec(sqlite3* db, const char* sql, const std::string& path) {
  const int rc = sqlite3_exec(db, sql, nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK) {
    return Status::IoError(std::string(sql) + " failed on " + path + ": " + SqliteMessage(db, rc));
  }
  return Status::Ok();
}

// ---------------------------------------------------------------------------------------------
// Reading back: rows are checked before they are decoded or hashed.

// Columns of kSelectLandmarks, in order.
enum LandmarkColumn {
  kLandmarkId = 0,
  kLandmarkPlace,
  kLandmarkSiftCount,
  kLandmarkPeaks,
  kLandmarkClass,
  kLandmarkBoxX,
  kLandmarkBoxY,
  kLandmarkBoxW,
  kLandmarkBoxH,
  kLandmarkNumDescriptors,
  kLandmarkDescriptors,
  kLandmarkKeypoints,
};
constexpr char kSelectLandmarks[] =
    "SELECT id, place_id, sift_count, colour_peaks, segment_class, box_x, box_y, box_w, box_h, "
    "num_descriptors, descriptors, keypoints FROM landmarks ORDER BY id";

constexpr char kSelectPlaces[] =
    "SELECT id, robot, sequence, utime, num_landmarks, image_width FROM places ORDER BY id";

// One landmark row, checked, with its BLOBs still in SQLite's buffers (valid until the next step).
struct LandmarkRow {
  int64_t id = 0;
  int64_t place = 0;
  int64_t sift_count = 0;
  std::pair<const uint8_t*, size_t> peaks;
  int64_t segment_class = 0;
  int64_t box[4] = {0, 0, 0, 0};
  int64_t num_descriptors = 0;
  std::pair<const uint8_t*, size_t> descriptors;
  std::pair<const uint8_t*, size_t> keypoints;
};

// Reads an INTEGER column that must lie in [low, high].
bool ReadInt(const Statement& row, int column, int64_t low, int64_t high, int64_t* value) {
  if (row.ColumnType(column) != SQLITE_INTEGER) return false;
  *value = row.ColumnInt(column);
  return *value >= low && *value <= high;
}

Status ReadLandmarkRow(const Statement& row, const std::string& store, LandmarkRow* out) {
  out->id = row.ColumnInt(kLandmarkId);
  const auto corrupt = [&](const std::string& what) {
    return Status::IoError(store + ": landmark " + std::to_string(out->id) +
                           " is corrupt: " + what);
  };
  const struct {
    int column;
    const char* name;
    int64_t low, high;
    int64_t* value;
  } ints[] = {
      {kLandmarkPlace, "place_id", 0, INT64_MAX, &out->place},
      {kLandmarkSiftCount, "sift_count", 0, INT_MAX, &out->sift_count},
      {kLandmarkClass, "segment_class", 0, 255, &out->segment_class},
      {kLandmarkBoxX, "box_x", INT_MIN, INT_MAX, &out->box[0]},
      {kLandmarkBoxY, "box_y", INT_MIN, INT_MAX, &out->box[1]},
      {kLandmarkBoxW, "box_w", 0, INT_MAX, &out->box[2]},
      {kLandmarkBoxH, "box_h", 0, INT_MAX, &out->box[3]},
      {kLandmarkNumDescriptors, "num_descriptors", 0, INT_MAX / kDescriptorSize,
       &out->num_descriptors},
  };
  for (const auto& field : ints) {
    if (!ReadInt(row, field.column, field.low, field.high, field.value)) {
      return corrupt(std::string(field.name) + " is missing or out of range");
    }
  }
  if (!IsKnownSegmentClass(out->segment_class)) {
    return corrupt("unknown segment_class " + std::to_string(out->segment_class));
  }
  out->peaks = row.ColumnBlob(kLandmarkPeaks);
  out->descriptors = row.ColumnBlob(kLandmarkDescriptors);
  out->keypoints = row.ColumnBlob(kLandmarkKeypoints);
  if (out->peaks.second % kPeakBytes != 0) {
    return corrupt("colour_peaks holds " + std::to_string(out->peaks.second) +
                   " bytes, not a multiple of " + std::to_string(kPeakBytes));
  }
  const size_t n = static_cast<size_t>(out->num_descriptors);
  if (out->descriptors.second != n * kDescriptorSize) {
    return corrupt("descriptors holds " + std::to_string(out->descriptors.second) + " bytes, " +
                   std::to_string(n) + " descriptors need " + std::to_string(n * kDescriptorSize));
  }
  if (out->keypoints.second != n * kKeypointBytes) {
    return corrupt("keypoints holds " + std::to_string(out->keypoints.second) + " bytes, " +
                   std::to_string(n) + " keypoints need " + std::to_string(n * kKeypointBytes));
  }
  return Status::Ok();
}

Landmark DecodeLandmark(const LandmarkRow& row) {
  Landmark landmark;
  landmark.id = LandmarkId(row.id);
  landmark.place = PlaceId(row.place);
  landmark.sift_count = static_cast<int>(row.sift_count);
  const size_t num_peaks = row.peaks.second / kPeakBytes;
  landmark.colour.peaks.resize(num_peaks);
  for (size_t i = 0; i < num_peaks; ++i) {
    landmark.colour.peaks[i] = ReadFloat(row.peaks.first + i * kPeakBytes);
  }
  landmark.segment_class = static_cast<SegmentClass>(row.segment_class);
  landmark.box = cv::Rect(static_cast<int>(row.box[0]), static_cast<int>(row.box[1]),
                          static_cast<int>(row.box[2]), static_cast<int>(row.box[3]));
  const int n = static_cast<int>(row.num_descriptors);
  landmark.descriptors.create(n, kDescriptorSize, CV_8U);
  if (n > 0) std::memcpy(landmark.descriptors.data, row.descriptors.first, row.descriptors.second);
  landmark.keypoints.resize(n);
  for (int i = 0; i < n; ++i) {
    const uint8_t* bytes = row.keypoints.first + static_cast<size_t>(i) * kKeypointBytes;
    landmark.keypoints[i] = cv::KeyPoint(ReadFloat(bytes), ReadFloat(bytes + 4),
                                         ReadFloat(bytes + 8), ReadFloat(bytes + 12));
  }
  return landmark;
}

// The canonical serialization of a landmark: tag 'L', then id, place, sift_count, number of
// peaks, the peaks (float32 LE), segment class, box x, y, w, h, number of descriptors, the
// descriptor bytes, the keypoints (x, y, size, angle as float32 LE). Integers are 8 bytes LE. The
// v1 BLOBs are already in this form, so they are hashed as stored.
void HashLandmark(const LandmarkRow& row, Fnv1a64* hash) {
  hash->Byte('L');
  hash->Int(row.id);
  hash->Int(row.place);
  hash->Int(row.sift_count);
  hash->Int(static_cast<int64_t>(row.peaks.second / kPeakBytes));
  hash->Bytes(row.peaks.first, row.peaks.second);
  hash->Int(row.segment_class);
  for (int64_t value : row.box) hash->Int(value);
  hash->Int(row.num_descriptors);
  hash->Bytes(row.descriptors.first, row.descriptors.second);
  hash->Bytes(row.keypoints.first, row.keypoints.second);
}

// Tag 'P', then id, robot length, robot bytes, sequence, utime, num_landmarks, image_width.
void HashPlace(const Place& place, Fnv1a64* hash) {
  hash->Byte('P');
  hash->Int(place.id.value());
  hash->Int(static_cast<int64_t>(place.robot.size()));
  hash->Bytes(reinterpret_cast<const uint8_t*>(place.robot.data()), place.robot.size());
  hash->Int(place.sequence);
  hash->Int(place.utime);
  hash->Int(place.num_landmarks);
  hash->Int(place.image_width);
}

// ---------------------------------------------------------------------------------------------

class SqliteStore final : public LandmarkStore {
 public:
  SqliteStore(std::string path, Connection db, Statement insert_place, Statement insert_landmark)
      : path_(std::move(path)),
        db_(std::move(db)),
        insert_place_(std::move(insert_place)),
        insert_landmark_(std::move(insert_landmark)) {}

  Status AddPlace(Place* place, std::vector<Landmark>* landmarks) override;
  Status LoadPlaces(const std::function<void(const Place&)>& visit) const override;
  Status LoadLandmarks(const std::function<void(Landmark&&)>& visit) const override;
  StatusOr<StoreCounts> Counts() const override;
  StatusOr<uint64_t> Checksum() const override;
  std::string Describe() const override { return "sqlite:" + path_; }

 private:
  Status Error(const std::string& what, int rc) const {
    return Status::IoError(Describe() + ": " + what + ": " + SqliteMessage(db_.get(), rc));
  }
  // Streams places (with ids) to `visit`; the caller holds mutex_.
  Status ScanPlaces(const std::function<void(const Place&)>& visit) const;
  // Streams checked landmark rows to `visit`; the caller holds mutex_.
  Status ScanLandmarks(const std::function<void(const LandmarkRow&)>& visit) const;

  const std::string path_;
  // Serialises every call: SQLite connections must not be used by two threads at once, and the
  // server reads counts from its status thread while a worker writes.
  mutable std::mutex mutex_;
  Connection db_;  // declared before the statements so that it is closed after them
  Statement insert_place_;
  Statement insert_landmark_;
  // Encoding buffers reused across AddPlace calls.
  std::vector<uint8_t> peaks_buffer_;
  std::vector<uint8_t> keypoints_buffer_;
};

Status SqliteStore::AddPlace(Place* place, std::vector<Landmark>* landmarks) {
  if (place == nullptr) return Status::InvalidArgument("AddPlace needs a place");
  static const std::vector<Landmark> kNoLandmarks;
  const std::vector<Landmark>& items = landmarks != nullptr ? *landmarks : kNoLandmarks;
  PLACEREC_RETURN_IF_ERROR(ValidatePlaceAndLandmarks(*place, items));

  std::lock_guard<std::mutex> lock(mutex_);
  sqlite3* db = db_.get();
  int64_t place_id = 0;
  std::vector<int64_t> landmark_ids;
  landmark_ids.reserve(items.size());
  {
    Transaction transaction(db);
    int rc = transaction.Begin(/*immediate=*/true);
    if (rc != SQLITE_OK) return Error("cannot start a write transaction", rc);
    {
      ScopedReset reset(&insert_place_);
      insert_place_.BindText(1, place->robot);
      insert_place_.BindInt(2, place->sequence);
      insert_place_.BindInt(3, place->utime);
      insert_place_.BindInt(4, static_cast<int64_t>(items.size()));
      insert_place_.BindInt(5, place->image_width);
      rc = insert_place_.Step();
      if (rc == SQLITE_CONSTRAINT_UNIQUE) {
        return Status::InvalidArgument("place robot/sequence already stored: robot '" +
                                       place->robot + "' sequence " +
                                       std::to_string(place->sequence));
      }
      if (rc != SQLITE_DONE) return Error("cannot insert place", rc);
      place_id = sqlite3_last_insert_rowid(db);
    }
    for (size_t i = 0; i < items.size(); ++i) {
      const Landmark& landmark = items[i];
      ScopedReset reset(&insert_landmark_);
      EncodePeaks(landmark.colour, &peaks_buffer_);
      EncodeKeypoints(landmark.keypoints, &keypoints_buffer_);
      const size_t num_descriptors = landmark.keypoints.size();  // == rows, validated
      insert_landmark_.BindInt(1, place_id);
      insert_landmark_.BindInt(2, landmark.sift_count);
      insert_landmark_.BindBlob(3, peaks_buffer_.data(), peaks_buffer_.size());
      insert_landmark_.BindInt(4, static_cast<int64_t>(landmark.segment_class));
      insert_landmark_.BindInt(5, landmark.box.x);
      insert_landmark_.BindInt(6, landmark.box.y);
      insert_landmark_.BindInt(7, landmark.box.width);
      insert_landmark_.BindInt(8, landmark.box.height);
      insert_landmark_.BindInt(9, static_cast<int64_t>(num_descriptors));
      insert_landmark_.BindBlob(10, num_descriptors > 0 ? landmark.descriptors.data : nullptr,
                                num_descriptors * kDescriptorSize);
      insert_landmark_.BindBlob(11, keypoints_buffer_.data(), keypoints_buffer_.size());
      rc = insert_landmark_.Step();
      if (rc != SQLITE_DONE) return Error("cannot insert landmark " + std::to_string(i), rc);
      landmark_ids.push_back(sqlite3_last_insert_rowid(db));
    }
    rc = transaction.Commit();
    if (rc != SQLITE_OK) return Error("cannot commit place", rc);
  }

  // Committed: only now do the inputs learn their ids.
  place->id = PlaceId(place_id);
  place->num_landmarks = static_cast<int>(items.size());
  if (landmarks != nullptr) {
    for (size_t i = 0; i < landmarks->size(); ++i) {
      (*landmarks)[i].id = LandmarkId(landmark_ids[i]);
      (*landmarks)[i].place = place->id;
    }
  }
  return Status::Ok();
}

Status SqliteStore::ScanPlaces(const std::function<void(const Place&)>& visit) const {
  Statement select;
  int rc = Statement::Prepare(db_.get(), kSelectPlaces, false, &select);
  if (rc != SQLITE_OK) return Error("cannot read places", rc);
  while ((rc = select.Step()) == SQLITE_ROW) {
    Place place;
    place.id = PlaceId(select.ColumnInt(0));
    int64_t num_landmarks = 0;
    int64_t image_width = 0;
    // Types first: reading a column as another type converts it.
    if (select.ColumnType(1) != SQLITE_TEXT || select.ColumnType(2) != SQLITE_INTEGER ||
        select.ColumnType(3) != SQLITE_INTEGER || !ReadInt(select, 4, 0, INT_MAX, &num_landmarks) ||
        !ReadInt(select, 5, 0, INT_MAX, &image_width)) {
      return Status::IoError(Describe() + ": place " + std::to_string(place.id.value()) +
                             " is corrupt: a field is missing or out of range");
    }
    place.robot = select.ColumnText(1);
    place.sequence = select.ColumnInt(2);
    place.utime = select.ColumnInt(3);
    place.num_landmarks = static_cast<int>(num_landmarks);
    place.image_width = static_cast<int>(image_width);
    visit(place);
  }
  if (rc != SQLITE_DONE) return Error("cannot read places", rc);
  return Status::Ok();
}

Status SqliteStore::ScanLandmarks(const std::function<void(const LandmarkRow&)>& visit) const {
  Statement select;
  int rc = Statement::Prepare(db_.get(), kSelectLandmarks, false, &select);
  if (rc != SQLITE_OK) return Error("cannot read landmarks", rc);
  LandmarkRow row;
  while ((rc = select.Step()) == SQLITE_ROW) {
    PLACEREC_RETURN_IF_ERROR(ReadLandmarkRow(select, Describe(), &row));
    visit(row);
  }
  if (rc != SQLITE_DONE) return Error("cannot read landmarks", rc);
  return Status::Ok();
}

Status SqliteStore::LoadPlaces(const std::function<void(const Place&)>& visit) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return ScanPlaces(visit);
}

Status SqliteStore::LoadLandmarks(const std::function<void(Landmark&&)>& visit) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return ScanLandmarks([&visit](const LandmarkRow& row) { visit(DecodeLandmark(row)); });
}

StatusOr<StoreCounts> SqliteStore::Counts() const {
  std::lock_guard<std::mutex> lock(mutex_);
  // One statement, so one consistent snapshot.
  Statement select;
  int rc = Statement::Prepare(db_.get(),
                              "SELECT (SELECT COUNT(*) FROM places), "
                              "(SELECT COUNT(*) FROM landmarks), "
                              "(SELECT COALESCE(SUM(num_descriptors), 0) FROM landmarks)",
                              false, &select);
  if (rc == SQLITE_OK) rc = select.Step();
  if (rc != SQLITE_ROW) return Error("cannot count the map", rc);
  StoreCounts counts;
  counts.places = select.ColumnInt(0);
  counts.landmarks = select.ColumnInt(1);
  counts.descriptors = select.ColumnInt(2);
  return counts;
}

StatusOr<uint64_t> SqliteStore::Checksum() const {
  std::lock_guard<std::mutex> lock(mutex_);
  // Places and landmarks from the same snapshot even if another connection writes meanwhile.
  Transaction transaction(db_.get());
  const int rc = transaction.Begin(/*immediate=*/false);
  if (rc != SQLITE_OK) return Error("cannot start a read transaction", rc);
  Fnv1a64 hash;
  PLACEREC_RETURN_IF_ERROR(ScanPlaces([&hash](const Place& place) { HashPlace(place, &hash); }));
  PLACEREC_RETURN_IF_ERROR(
      ScanLandmarks([&hash](const LandmarkRow& row) { HashLandmark(row, &hash); }));
  // Nothing was written; the destructor ends the read transaction.
  return hash.digest();
}

}  // namespace

bool SqliteStoreOptions::Check(std::string* error) const {
  if (busy_timeout_ms < 0) {
    *error = "sqlite busy_timeout_ms must be >= 0";
    return false;
  }
  return true;
}

StatusOr<std::unique_ptr<LandmarkStore>> OpenSqliteStore(const std::string& path,
                                                         const SqliteStoreOptions& options) {
  std::string error;
  if (!options.Check(&error)) return Status::InvalidArgument(error);
  if (path.empty()) return Status::InvalidArgument("sqlite store path is empty");
  const bool in_memory = path == ":memory:";
  if (options.must_exist && !in_memory) {
    std::error_code ignored;
    if (!std::filesystem::exists(path, ignored)) {
      return Status::NotFound("no placerec map at " + path + " (it must exist)");
    }
  }

  // The object's mutex serialises use of the connection, so SQLite's own mutex is not needed.
  int flags = SQLITE_OPEN_READWRITE | SQLITE_OPEN_NOMUTEX;
  if (!options.must_exist) flags |= SQLITE_OPEN_CREATE;
  sqlite3* raw = nullptr;
  int rc = sqlite3_open_v2(path.c_str(), &raw, flags, nullptr);
  Connection db(raw);
  if (rc != SQLITE_OK) {
    return Status::IoError("cannot open map " + path + ": " + SqliteMessage(raw, rc));
  }
  sqlite3_extended_result_codes(db.get(), 1);
  sqlite3_busy_timeout(db.get(), options.busy_timeout_ms);

  // Refuse what is not ours before changing anything in the file.
  StatusOr<int> version = ReadSchemaVersion(db.get(), path);
  if (!version.ok()) return version.status();
  if (*version > kSqliteSchemaVersion) return NewerVersionError(path, *version);
  if (*version == 0 && options.must_exist) {
    return Status::NotFound(path + " holds no placerec map (an empty database)");
  }

  PLACEREC_RETURN_IF_ERROR(Exec(db.get(), "PRAGMA foreign_keys = ON", path));
  {
    Statement journal;
    rc = Statement::Prepare(db.get(), "PRAGMA journal_mode = WAL", false, &journal);
    if (rc == SQLITE_OK) rc = journal.Step();
    if (rc != SQLITE_ROW) {
      return Status::IoError("cannot set the WAL journal on " + path + ": " +
                             SqliteMessage(db.get(), rc));
    }
    const std::string mode = journal.ColumnText(0);
    LOG_IF(WARNING, !in_memory && mode != "wal")
        << "placerec map " << path << " runs with journal mode " << mode << ", not wal";
  }
  PLACEREC_RETURN_IF_ERROR(
      Exec(db.get(),
           options.synchronous_full ? "PRAGMA synchronous = FULL" : "PRAGMA synchronous = NORMAL",
           path));
  if (*version < kSqliteSchemaVersion) {
    PLACEREC_RETURN_IF_ERROR(MigrateToCurrent(db.get(), path));
  }

  Statement insert_place;
  Statement insert_landmark;
  rc = Statement::Prepare(db.get(),
                          "INSERT INTO places(robot, sequence, utime, num_landmarks, image_width) "
                          "VALUES(?, ?, ?, ?, ?)",
                          true, &insert_place);
  if (rc == SQLITE_OK) {
    rc = Statement::Prepare(db.get(),
                            "INSERT INTO landmarks(place_id, sift_count, colour_peaks, "
                            "segment_class, box_x, box_y, box_w, box_h, num_descriptors, "
                            "descriptors, keypoints) VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                            true, &insert_landmark);
  }
  if (rc != SQLITE_OK) {
    return Status::IoError("cannot prepare statements on " + path + ": " +
                           SqliteMessage(db.get(), rc));
  }
  return std::unique_ptr<LandmarkStore>(std::make_unique<SqliteStore>(
      path, std::move(db), std::move(insert_place), std::move(insert_landmark)));
}

}  // namespace placerec
