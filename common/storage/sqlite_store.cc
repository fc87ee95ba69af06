#include "common/storage/sqlite_store.h"

#include <unistd.h>

#include <algorithm>
#include <climits>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <optional>
#include <regex>
#include <set>
#include <sstream>
#include <system_error>
#include <unordered_map>
#include <utility>
#include <vector>

#include "common/features/features.h"
#include "common/storage/blob_codec.h"
#include "common/storage/checksum.h"
#include "common/storage/sqlite_db.h"
#include "common/util/logging.h"
#include "common/util/memory.h"

namespace placerec {
namespace {

// A map file is read ahead in order before quick_check when it takes at most this share of the
// memory the system has available (a larger one would push its own first pages out again).
constexpr double kReadAheadShare = 0.5;

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
  kLandmarkObjectClass,
  kLandmarkClassConfidence,
};
// The columns of LandmarkColumn, in order; those a map of schema v1 has, then v2's two.
#define PLACEREC_LANDMARK_V1_COLUMNS                                                    \
  "id, place_id, sift_count, colour_peaks, segment_class, box_x, box_y, box_w, box_h, " \
  "num_descriptors, descriptors, keypoints"
#define PLACEREC_LANDMARK_COLUMNS PLACEREC_LANDMARK_V1_COLUMNS ", object_class, class_confidence"
constexpr char kSelectLandmarks[] =
    "SELECT " PLACEREC_LANDMARK_COLUMNS " FROM landmarks ORDER BY id";
// The same from a map of schema v1 opened read-only (not upgraded): no class, as the v1 -> v2
// step leaves its landmarks.
constexpr char kSelectV1Landmarks[] =
    "SELECT " PLACEREC_LANDMARK_V1_COLUMNS ", NULL, 0 FROM landmarks ORDER BY id";

constexpr char kSelectPlaces[] =
    "SELECT id, robot, sequence, utime, num_landmarks, image_width FROM places ORDER BY id";

constexpr char kInsertPlace[] =
    "INSERT INTO places(robot, sequence, utime, num_landmarks, image_width) VALUES(?, ?, ?, ?, ?)";

constexpr char kInsertSighting[] = "INSERT INTO sightings(place_id, landmark_id) VALUES(?, ?)";
constexpr char kInsertThumbnail[] = "INSERT INTO thumbnails(place_id, jpeg) VALUES(?, ?)";
constexpr char kSelectThumbnail[] = "SELECT jpeg FROM thumbnails WHERE place_id = ?";
constexpr char kSelectSightings[] =
    "SELECT place_id, landmark_id FROM sightings ORDER BY place_id, landmark_id";
constexpr char kInsertLandmark[] =
    "INSERT INTO landmarks(place_id, sift_count, colour_peaks, segment_class, box_x, box_y, box_w, "
    "box_h, num_descriptors, descriptors, keypoints, object_class, class_confidence) "
    "VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)";

constexpr char kSelectPlaceById[] =
    "SELECT robot, sequence, utime, num_landmarks, image_width FROM places WHERE id = ?";
constexpr char kSelectLandmarkById[] =
    "SELECT " PLACEREC_LANDMARK_COLUMNS " FROM landmarks WHERE id = ?";
// The same from a map of schema v1 (RepairSqliteMap reads a map as it is): no class, as the
// v1 -> v2 step leaves its landmarks.
constexpr char kSelectV1LandmarkById[] =
    "SELECT " PLACEREC_LANDMARK_V1_COLUMNS ", NULL, 0 FROM landmarks WHERE id = ?";
#undef PLACEREC_LANDMARK_COLUMNS
#undef PLACEREC_LANDMARK_V1_COLUMNS

// What every refusal of a damaged map ends with.
constexpr char kDamagedMapAdvice[] =
    "restore the map from a backup, or repair it: placerec-server --repair drops the damaged "
    "places, reports how many, and keeps the damaged file beside the map";

// Reads an INTEGER column that must lie in [low, high].
bool ReadInt(const SqliteStatement& row, int column, int64_t low, int64_t high, int64_t* value) {
  if (row.ColumnType(column) != SQLITE_INTEGER) return false;
  *value = row.ColumnInt(column);
  return *value >= low && *value <= high;
}

ByteView ReadBlob(const SqliteStatement& row, int column) {
  const auto [data, size] = row.ColumnBlob(column);
  return {data, size};
}

// Reads and checks one row of kSelectLandmarks; its BLOBs stay in SQLite's buffers (valid until
// the next step). `store` names the map in errors.
Status ReadLandmarkRow(const SqliteStatement& row, const std::string& store, EncodedLandmark* out) {
  out->id = row.ColumnInt(kLandmarkId);
  const auto corrupt = [&](const std::string& what) {
    return Status::IoError(store + ": landmark " + std::to_string(out->id) +
                           " is corrupt: " + what + "; " + kDamagedMapAdvice);
  };
  if (out->id < 1) return corrupt("its id is not positive");
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
  // The class: NULL (unclassified, every landmark of a v1 map) or a name as Landmark::Validate
  // allows, with a confidence in [0, 1] (0 without a class).
  out->object_class.clear();
  out->class_confidence = 0.0f;
  const int class_type = row.ColumnType(kLandmarkObjectClass);
  const int confidence_type = row.ColumnType(kLandmarkClassConfidence);
  if (class_type != SQLITE_NULL) {
    if (class_type != SQLITE_TEXT) return corrupt("object_class is not text");
    out->object_class = row.ColumnText(kLandmarkObjectClass);
  }
  if (confidence_type != SQLITE_FLOAT && confidence_type != SQLITE_INTEGER) {
    return corrupt("class_confidence is missing");
  }
  out->class_confidence = static_cast<float>(row.ColumnDouble(kLandmarkClassConfidence));
  {
    Landmark check;  // the class rules live in one place
    check.object_class = out->object_class;
    check.class_confidence = out->class_confidence;
    const Status valid = check.Validate();
    if (!valid.ok()) return corrupt(valid.message());
  }
  out->peaks = ReadBlob(row, kLandmarkPeaks);
  out->descriptors = ReadBlob(row, kLandmarkDescriptors);
  out->keypoints = ReadBlob(row, kLandmarkKeypoints);
  const Status blobs = CheckLandmarkBlobs(*out);
  if (!blobs.ok()) return corrupt(blobs.message());
  return Status::Ok();
}

// ---------------------------------------------------------------------------------------------

class SqliteStore final : public LandmarkStore {
 public:
  // A store that writes: `version` is the current schema's.
  SqliteStore(std::string path, SqliteConnection db, SqliteStatement insert_place,
              SqliteStatement insert_landmark)
      : path_(std::move(path)),
        db_(std::move(db)),
        version_(kSqliteSchemaVersion),
        read_only_(false),
        insert_place_(std::move(insert_place)),
        insert_landmark_(std::move(insert_landmark)) {}
  // A read-only store of a map of schema `version` (read as it is).
  SqliteStore(std::string path, SqliteConnection db, int version)
      : path_(std::move(path)), db_(std::move(db)), version_(version), read_only_(true) {}

  Status AddPlace(Place* place, std::vector<Landmark>* landmarks) override;
  Status LoadPlaces(const std::function<void(const Place&)>& visit) const override;
  Status LoadLandmarks(const std::function<void(Landmark&&)>& visit) const override;
  StatusOr<std::vector<uint8_t>> LoadThumbnail(PlaceId place) const override;
  StatusOr<StoreCounts> Counts() const override;
  StatusOr<uint64_t> Checksum() const override;
  std::string Describe() const override { return "sqlite:" + path_; }
  // "MAP.index" beside the map file: a cache rewritten whole (never part of a transaction, so
  // writing it neither blocks the map's writers nor grows its WAL), and removed with the map.
  std::string IndexSnapshotPath() const override {
    return path_.empty() || path_ == ":memory:" ? "" : path_ + ".index";
  }

 private:
  // A read-only store of an older map reads the version again (the caller holds mutex_).
  void RefreshVersion() const {
    if (!read_only_ || version_ >= kSqliteSchemaVersion) return;
    const StatusOr<int> version = ReadSchemaVersion(db_.get(), path_);
    if (version.ok() && *version > version_ && *version <= kSqliteSchemaVersion) {
      version_ = *version;
    }
  }
  Status Error(const std::string& what, int rc) const {
    return Status::IoError(Describe() + ": " + what + ": " + SqliteMessage(db_.get(), rc));
  }
  // Inserts the rows of a validated place and its landmarks, inside the caller's transaction;
  // returns the new ids. The caller holds mutex_.
  Status InsertRows(const Place& place, const std::vector<Landmark>& landmarks, int64_t* place_id,
                    std::vector<int64_t>* landmark_ids);
  // Streams places (with ids) to `visit`; the caller holds mutex_.
  Status ScanPlaces(const std::function<void(const Place&)>& visit) const;
  // Streams checked landmark rows to `visit`; the caller holds mutex_.
  Status ScanLandmarks(const std::function<void(const EncodedLandmark&)>& visit) const;

  const std::string path_;
  // Serialises every call: SQLite connections must not be used by two threads at once, and the
  // server reads counts from its status thread while a worker writes.
  mutable std::mutex mutex_;
  SqliteConnection db_;  // declared before the statements so that it is closed after them
  // The file's schema version: the current one, or an older one when opened read-only (read
  // again before each read while older: a server may upgrade the map meanwhile).
  mutable int version_;
  const bool read_only_;
  SqliteStatement insert_place_;
  SqliteStatement insert_landmark_;
  // Encoding buffers reused across AddPlace calls.
  LandmarkBlobBuffers blob_buffers_;
};

Status SqliteStore::AddPlace(Place* place, std::vector<Landmark>* landmarks) {
  if (place == nullptr) return Status::InvalidArgument("AddPlace needs a place");
  static const std::vector<Landmark> kNoLandmarks;
  const std::vector<Landmark>& items = landmarks != nullptr ? *landmarks : kNoLandmarks;
  PLACEREC_RETURN_IF_ERROR(ValidatePlaceAndLandmarks(*place, items));
  if (read_only_) {
    return Status::InvalidArgument(Describe() + " is open for reading only; nothing was written");
  }

  std::lock_guard<std::mutex> lock(mutex_);
  int64_t place_id = 0;
  std::vector<int64_t> landmark_ids;
  landmark_ids.reserve(items.size());
  {
    SqliteTransaction transaction(db_.get());
    int rc = transaction.Begin(/*immediate=*/true);
    if (rc != SQLITE_OK) return Error("cannot start a write transaction", rc);
    PLACEREC_RETURN_IF_ERROR(InsertRows(*place, items, &place_id, &landmark_ids));
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

Status SqliteStore::InsertRows(const Place& place, const std::vector<Landmark>& landmarks,
                               int64_t* place_id, std::vector<int64_t>* landmark_ids) {
  sqlite3* db = db_.get();
  {
    ScopedStatementReset reset(&insert_place_);
    insert_place_.BindText(1, place.robot);
    insert_place_.BindInt(2, place.sequence);
    insert_place_.BindInt(3, place.utime);
    insert_place_.BindInt(4, static_cast<int64_t>(landmarks.size()));
    insert_place_.BindInt(5, place.image_width);
    const int rc = insert_place_.Step();
    if (rc == SQLITE_CONSTRAINT_UNIQUE) {
      return Status::InvalidArgument("place robot/sequence already stored: robot '" + place.robot +
                                     "' sequence " + std::to_string(place.sequence));
    }
    if (rc != SQLITE_DONE) return Error("cannot insert place", rc);
    *place_id = sqlite3_last_insert_rowid(db);
  }
  if (!place.thumbnail.empty()) {
    SqliteStatement insert;
    int rc = SqliteStatement::Prepare(db, kInsertThumbnail, false, &insert);
    if (rc == SQLITE_OK) {
      insert.BindInt(1, *place_id);
      insert.BindBlob(2, place.thumbnail.data(), place.thumbnail.size());
      rc = insert.Step();
    }
    if (rc != SQLITE_DONE) return Error("cannot insert thumbnail", rc);
  }
  for (const LandmarkId seen : place.seen_landmarks) {
    SqliteStatement insert;
    int rc = SqliteStatement::Prepare(db, kInsertSighting, false, &insert);
    if (rc == SQLITE_OK) {
      insert.BindInt(1, *place_id);
      insert.BindInt(2, seen.value());
      rc = insert.Step();
    }
    if (rc == SQLITE_CONSTRAINT_FOREIGNKEY) {
      return Status::InvalidArgument("place sees landmark " + std::to_string(seen.value()) +
                                     ", which is not in the map");
    }
    if (rc != SQLITE_DONE) return Error("cannot insert sighting", rc);
  }
  for (size_t i = 0; i < landmarks.size(); ++i) {
    ScopedStatementReset reset(&insert_landmark_);
    const EncodedLandmark encoded = EncodeLandmark(landmarks[i], &blob_buffers_);
    insert_landmark_.BindInt(1, *place_id);
    insert_landmark_.BindInt(2, encoded.sift_count);
    insert_landmark_.BindBlob(3, encoded.peaks.data, encoded.peaks.size);
    insert_landmark_.BindInt(4, encoded.segment_class);
    for (int k = 0; k < 4; ++k) insert_landmark_.BindInt(5 + k, encoded.box[k]);
    insert_landmark_.BindInt(9, encoded.num_descriptors);
    insert_landmark_.BindBlob(10, encoded.descriptors.data, encoded.descriptors.size);
    insert_landmark_.BindBlob(11, encoded.keypoints.data, encoded.keypoints.size);
    if (encoded.object_class.empty()) {
      insert_landmark_.BindNull(12);
    } else {
      insert_landmark_.BindText(12, encoded.object_class);
    }
    insert_landmark_.BindDouble(13, encoded.class_confidence);
    const int rc = insert_landmark_.Step();
    if (rc != SQLITE_DONE) return Error("cannot insert landmark " + std::to_string(i), rc);
    landmark_ids->push_back(sqlite3_last_insert_rowid(db));
  }
  return Status::Ok();
}

Status SqliteStore::ScanPlaces(const std::function<void(const Place&)>& visit) const {
  // Sightings first (few: only the seed's recognition mode writes them), then every place.
  std::unordered_map<int64_t, std::vector<LandmarkId>> seen;
  if (version_ >= 2) {  // sightings came with schema v2
    SqliteStatement sightings;
    int rc = SqliteStatement::Prepare(db_.get(), kSelectSightings, false, &sightings);
    if (rc == SQLITE_OK) {
      while ((rc = sightings.Step()) == SQLITE_ROW) {
        seen[sightings.ColumnInt(0)].push_back(LandmarkId(sightings.ColumnInt(1)));
      }
    }
    if (rc != SQLITE_DONE) return Error("cannot read sightings", rc);
  }
  SqliteStatement select;
  int rc = SqliteStatement::Prepare(db_.get(), kSelectPlaces, false, &select);
  if (rc != SQLITE_OK) return Error("cannot read places", rc);
  while ((rc = select.Step()) == SQLITE_ROW) {
    Place place;
    place.id = PlaceId(select.ColumnInt(0));
    int64_t num_landmarks = 0;
    int64_t image_width = 0;
    // Types first: reading a column as another type converts it.
    if (!place.id.IsValid() || select.ColumnType(1) != SQLITE_TEXT ||
        select.ColumnType(2) != SQLITE_INTEGER || select.ColumnType(3) != SQLITE_INTEGER ||
        !ReadInt(select, 4, 0, INT_MAX, &num_landmarks) ||
        !ReadInt(select, 5, 0, INT_MAX, &image_width)) {
      return Status::IoError(Describe() + ": place " + std::to_string(place.id.value()) +
                             " is corrupt: a field is missing or out of range");
    }
    place.robot = select.ColumnText(1);
    place.sequence = select.ColumnInt(2);
    place.utime = select.ColumnInt(3);
    place.num_landmarks = static_cast<int>(num_landmarks);
    place.image_width = static_cast<int>(image_width);
    const auto sightings = seen.find(place.id.value());
    if (sightings != seen.end()) place.seen_landmarks = std::move(sightings->second);
    visit(place);
  }
  if (rc != SQLITE_DONE) return Error("cannot read places", rc);
  return Status::Ok();
}

Status SqliteStore::ScanLandmarks(const std::function<void(const EncodedLandmark&)>& visit) const {
  SqliteStatement select;
  int rc = SqliteStatement::Prepare(
      db_.get(), version_ >= 2 ? kSelectLandmarks : kSelectV1Landmarks, false, &select);
  if (rc != SQLITE_OK) return Error("cannot read landmarks", rc);
  EncodedLandmark row;
  while ((rc = select.Step()) == SQLITE_ROW) {
    PLACEREC_RETURN_IF_ERROR(ReadLandmarkRow(select, Describe(), &row));
    visit(row);
  }
  if (rc != SQLITE_DONE) return Error("cannot read landmarks", rc);
  return Status::Ok();
}

Status SqliteStore::LoadPlaces(const std::function<void(const Place&)>& visit) const {
  std::lock_guard<std::mutex> lock(mutex_);
  RefreshVersion();
  return ScanPlaces(visit);
}

Status SqliteStore::LoadLandmarks(const std::function<void(Landmark&&)>& visit) const {
  std::lock_guard<std::mutex> lock(mutex_);
  RefreshVersion();
  return ScanLandmarks([&visit](const EncodedLandmark& row) { visit(DecodeLandmark(row)); });
}

StatusOr<std::vector<uint8_t>> SqliteStore::LoadThumbnail(PlaceId place) const {
  std::lock_guard<std::mutex> lock(mutex_);
  RefreshVersion();
  if (version_ < 3) return std::vector<uint8_t>();  // thumbnails came with schema v3
  SqliteStatement select;
  int rc = SqliteStatement::Prepare(db_.get(), kSelectThumbnail, false, &select);
  if (rc == SQLITE_OK) {
    select.BindInt(1, place.value());
    rc = select.Step();
  }
  if (rc == SQLITE_DONE) return std::vector<uint8_t>();
  if (rc != SQLITE_ROW)
    return Error("cannot read the thumbnail of place " + std::to_string(place.value()), rc);
  if (select.ColumnType(0) != SQLITE_BLOB) {
    return Status::IoError(Describe() + ": the thumbnail of place " +
                           std::to_string(place.value()) + " is corrupt: not a BLOB");
  }
  const auto [bytes, size] = select.ColumnBlob(0);
  return std::vector<uint8_t>(bytes, bytes + size);
}

StatusOr<StoreCounts> SqliteStore::Counts() const {
  std::lock_guard<std::mutex> lock(mutex_);
  // One statement, so one consistent snapshot.
  SqliteStatement select;
  int rc = SqliteStatement::Prepare(db_.get(),
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
  SqliteTransaction transaction(db_.get());
  const int rc = transaction.Begin(/*immediate=*/false);
  if (rc != SQLITE_OK) return Error("cannot start a read transaction", rc);
  Fnv1a64 hash;
  PLACEREC_RETURN_IF_ERROR(ScanPlaces([&hash](const Place& place) { HashPlace(place, &hash); }));
  PLACEREC_RETURN_IF_ERROR(
      ScanLandmarks([&hash](const EncodedLandmark& row) { HashLandmark(row, &hash); }));
  // Nothing was written; the destructor ends the read transaction.
  return hash.digest();
}

// Opens the connection (creating the file unless options.must_exist) with extended result codes
// and the busy timeout.
StatusOr<SqliteConnection> OpenConnection(const std::string& path,
                                          const SqliteStoreOptions& options) {
  // The object's mutex serialises use of the connection, so SQLite's own mutex is not needed.
  int flags = SQLITE_OPEN_READWRITE | SQLITE_OPEN_NOMUTEX;
  if (!options.must_exist) flags |= SQLITE_OPEN_CREATE;
  return OpenSqliteDatabase(path, flags, options.busy_timeout_ms);
}

// Foreign keys on, WAL journal, the synchronous level of the options.
Status ConfigureConnection(sqlite3* db, const std::string& path,
                           const SqliteStoreOptions& options) {
  PLACEREC_RETURN_IF_ERROR(SqliteExec(db, "PRAGMA foreign_keys = ON", path));
  {
    SqliteStatement journal;
    int rc = SqliteStatement::Prepare(db, "PRAGMA journal_mode = WAL", false, &journal);
    if (rc == SQLITE_OK) rc = journal.Step();
    if (rc != SQLITE_ROW) {
      return Status::IoError("cannot set the WAL journal on " + path + ": " +
                             SqliteMessage(db, rc));
    }
    const std::string mode = journal.ColumnText(0);
    LOG_IF(WARNING, path != ":memory:" && mode != "wal")
        << "placerec map " << path << " runs with journal mode " << mode << ", not wal";
  }
  return SqliteExec(
      db, options.synchronous_full ? "PRAGMA synchronous = FULL" : "PRAGMA synchronous = NORMAL",
      path);
}

// SQLite's quick_check complaints about the open database (at most `limit`), one per element,
// without the "*** in database main ***" heading; empty when the file is whole.
std::vector<std::string> QuickCheck(sqlite3* db, int limit) {
  const std::string sql = "PRAGMA quick_check(" + std::to_string(limit) + ")";
  SqliteStatement check;
  int rc = SqliteStatement::Prepare(db, sql.c_str(), false, &check);
  if (rc != SQLITE_OK) return {"quick_check cannot run: " + SqliteMessage(db, rc)};
  std::vector<std::string> problems;
  while ((rc = check.Step()) == SQLITE_ROW) {
    std::istringstream lines(check.ColumnText(0));
    std::string line;
    while (std::getline(lines, line)) {
      if (line != "ok" && !line.empty() && line.rfind("*** in database", 0) != 0) {
        problems.push_back(line);
      }
    }
  }
  if (rc != SQLITE_DONE) problems.push_back("quick_check stopped: " + SqliteMessage(db, rc));
  return problems;
}

std::string Join(const std::vector<std::string>& parts, size_t max_parts) {
  std::string joined;
  for (size_t i = 0; i < parts.size() && i < max_parts; ++i) {
    joined += (i > 0 ? "; " : "") + parts[i];
  }
  if (parts.size() > max_parts) joined += "; ...";
  return joined;
}

// The places a quick_check complaint "On tree page P cell C: ..." names: the row of cell C of
// table leaf page P (read from the file, whose layout SQLite documents: page header, cell pointer
// array, cell = payload size and rowid varints) is a place, or a landmark whose place is read by
// its id. Complaints about anything else (interior pages, indexes, unused pages) name no place:
// rows under a damaged interior page fail to read and are dropped by the reading itself.
// `file` is the map, opened before the connection `db` and closed after it (closing a descriptor
// of the file drops every POSIX lock the process holds on it, SQLite's too).
std::set<int64_t> PlacesNamedByQuickCheck(sqlite3* db, std::ifstream& file,
                                          const std::vector<std::string>& problems) {
  std::set<int64_t> places;
  uint8_t header[100];
  if (!file.read(reinterpret_cast<char*>(header), sizeof(header))) return places;
  const uint32_t raw_page_size = (uint32_t{header[16]} << 8) | header[17];
  const size_t page_size = raw_page_size == 1 ? 65536 : raw_page_size;
  const std::regex cell_pattern("tree page ([0-9]+) cell ([0-9]+)");
  for (const std::string& problem : problems) {
    std::smatch match;
    if (!std::regex_search(problem, match, cell_pattern)) continue;
    const int64_t page = std::stoll(match[1].str());
    const size_t cell = std::stoul(match[2].str());
    if (page < 1 || page_size < 512) continue;
    std::vector<uint8_t> bytes(page_size);
    file.clear();
    file.seekg(static_cast<std::streamoff>((page - 1) * static_cast<int64_t>(page_size)));
    if (!file.read(reinterpret_cast<char*>(bytes.data()),
                   static_cast<std::streamsize>(page_size))) {
      continue;
    }
    const size_t base = page == 1 ? 100 : 0;
    if (bytes[base] != 0x0D) continue;  // not a table leaf
    const size_t cells = (size_t{bytes[base + 3]} << 8) | bytes[base + 4];
    const size_t pointer = base + 8 + 2 * cell;
    if (cell >= cells || pointer + 2 > page_size) continue;
    size_t at = (size_t{bytes[pointer]} << 8) | bytes[pointer + 1];
    // Two varints: the payload size (skipped), then the rowid.
    int64_t rowid = 0;
    for (int varint = 0; varint < 2; ++varint) {
      uint64_t value = 0;
      for (int i = 0; i < 9 && at < page_size; ++i) {
        const uint8_t b = bytes[at++];
        if (i == 8) {
          value = (value << 8) | b;
          break;
        }
        value = (value << 7) | (b & 0x7f);
        if ((b & 0x80) == 0) break;
      }
      rowid = static_cast<int64_t>(value);
    }
    // Which table the page belongs to.
    SqliteStatement owner;
    int rc =
        SqliteStatement::Prepare(db, "SELECT name FROM dbstat WHERE pageno = ?", false, &owner);
    if (rc == SQLITE_OK) {
      owner.BindInt(1, page);
      rc = owner.Step();
    }
    if (rc != SQLITE_ROW) continue;
    const std::string table = owner.ColumnText(0);
    if (table == "places") {
      places.insert(rowid);
    } else if (table == "landmarks") {
      SqliteStatement select;
      rc = SqliteStatement::Prepare(db, "SELECT place_id FROM landmarks WHERE id = ?", false,
                                    &select);
      if (rc == SQLITE_OK) {
        select.BindInt(1, rowid);
        rc = select.Step();
      }
      if (rc == SQLITE_ROW && select.ColumnType(0) == SQLITE_INTEGER) {
        places.insert(select.ColumnInt(0));
      }
    }
  }
  return places;
}

// A place read back whole with its landmarks, for RepairSqliteMap. Ids are the damaged map's,
// seen_landmarks too.
struct WholePlace {
  Place place;
  std::vector<Landmark> landmarks;
  bool sightings_unreadable = false;  // the place's sightings could not be read (left out)
  // The capture time stored, when it lay outside 0 .. kMaxUtime: place.utime holds the time the
  // server serves the place with (ClampCaptureTime), which a rewrite keeps.
  std::optional<int64_t> stored_utime;
};

// Reads place `id` and its landmarks by point lookups from a map of schema `version` (read as it
// is, not upgraded). Returns false with the reason in *why when the place row is missing (*why
// empty then) or anything of it is damaged.
bool ReadWholePlace(sqlite3* db, int version, const std::string& store, int64_t id, WholePlace* out,
                    std::string* why) {
  why->clear();
  const std::string name = "place " + std::to_string(id);
  SqliteStatement select;
  int rc = SqliteStatement::Prepare(db, kSelectPlaceById, false, &select);
  if (rc == SQLITE_OK) {
    select.BindInt(1, id);
    rc = select.Step();
  }
  if (rc == SQLITE_DONE) return false;  // no such row (ids may have gaps)
  if (rc != SQLITE_ROW) {
    *why = name + " cannot be read: " + SqliteMessage(db, rc);
    return false;
  }
  int64_t num_landmarks = 0;
  int64_t image_width = 0;
  if (select.ColumnType(0) != SQLITE_TEXT || select.ColumnType(1) != SQLITE_INTEGER ||
      select.ColumnType(2) != SQLITE_INTEGER || !ReadInt(select, 3, 0, INT_MAX, &num_landmarks) ||
      !ReadInt(select, 4, 0, INT_MAX, &image_width)) {
    *why = name + " is corrupt: a field is missing or out of range";
    return false;
  }
  out->place = Place();
  out->place.id = PlaceId(id);
  out->place.robot = select.ColumnText(0);
  out->place.sequence = select.ColumnInt(1);
  out->place.utime = select.ColumnInt(2);
  out->place.num_landmarks = static_cast<int>(num_landmarks);
  out->place.image_width = static_cast<int>(image_width);
  // The landmark ids from the (place_id, ...) index, then each row by its id.
  std::vector<int64_t> ids;
  SqliteStatement list;
  rc = SqliteStatement::Prepare(db, "SELECT id FROM landmarks WHERE place_id = ? ORDER BY id",
                                false, &list);
  if (rc == SQLITE_OK) {
    list.BindInt(1, id);
    while ((rc = list.Step()) == SQLITE_ROW) ids.push_back(list.ColumnInt(0));
  }
  if (rc != SQLITE_DONE) {
    *why = name + ": its landmarks cannot be listed: " + SqliteMessage(db, rc);
    return false;
  }
  if (static_cast<int64_t>(ids.size()) != num_landmarks) {
    *why = name + " has " + std::to_string(ids.size()) + " landmarks of its " +
           std::to_string(num_landmarks);
    return false;
  }
  out->landmarks.clear();
  for (int64_t landmark_id : ids) {
    SqliteStatement row;
    rc = SqliteStatement::Prepare(db, version >= 2 ? kSelectLandmarkById : kSelectV1LandmarkById,
                                  false, &row);
    if (rc == SQLITE_OK) {
      row.BindInt(1, landmark_id);
      rc = row.Step();
    }
    if (rc != SQLITE_ROW) {
      *why = name + ": landmark " + std::to_string(landmark_id) +
             " cannot be read: " + SqliteMessage(db, rc);
      return false;
    }
    EncodedLandmark encoded;
    const Status checked = ReadLandmarkRow(row, store, &encoded);
    if (!checked.ok() || encoded.place != id) {
      *why = name + ": landmark " + std::to_string(landmark_id) + " is corrupt";
      return false;
    }
    out->landmarks.push_back(DecodeLandmark(encoded));
  }
  // A time outside the range (an old build wrote such times) is no damage: the server serves the
  // place at the nearest end of the range (PlaceMap).
  out->stored_utime.reset();
  if (!CheckCaptureTime(out->place.utime).ok()) {
    out->stored_utime = out->place.utime;
    out->place.utime = ClampCaptureTime(out->place.utime);
  }
  // What AddPlace would refuse (a robot id out of the rules, ...) is damage too.
  const Status valid = ValidatePlaceAndLandmarks(out->place, out->landmarks);
  if (!valid.ok()) {
    *why = name + " is corrupt: " + valid.message();
    return false;
  }
  // The stored landmarks this place saw again (schema v2). A list that does not read costs the
  // sightings, not the place.
  out->sightings_unreadable = false;
  if (version >= 2) {
    SqliteStatement seen;
    rc = SqliteStatement::Prepare(
        db, "SELECT landmark_id FROM sightings WHERE place_id = ? ORDER BY landmark_id", false,
        &seen);
    if (rc == SQLITE_OK) {
      seen.BindInt(1, id);
      while ((rc = seen.Step()) == SQLITE_ROW) {
        // A value that is no integer names no landmark (the key would take '2abc' beside 2).
        if (seen.ColumnType(0) != SQLITE_INTEGER) continue;
        out->place.seen_landmarks.push_back(LandmarkId(seen.ColumnInt(0)));
      }
    }
    if (rc != SQLITE_DONE) {
      out->place.seen_landmarks.clear();
      out->sightings_unreadable = true;
    }
  }
  return true;
}

// The place's thumbnail for RepairSqliteMap, when the map has the table (schema v3) and the row
// reads back within the size limit; a picture that does not read is left behind (the place is
// whole without it).
std::vector<uint8_t> ReadThumbnailForRepair(sqlite3* db, int version, int64_t id) {
  if (version < 3) return {};
  SqliteStatement select;
  int rc = SqliteStatement::Prepare(db, kSelectThumbnail, false, &select);
  if (rc == SQLITE_OK) {
    select.BindInt(1, id);
    rc = select.Step();
  }
  if (rc != SQLITE_ROW || select.ColumnType(0) != SQLITE_BLOB) return {};
  const auto [bytes, size] = select.ColumnBlob(0);
  if (size > kMaxThumbnailBytes) return {};
  return std::vector<uint8_t>(bytes, bytes + size);
}

// Puts the map `fresh` (closed: one file) in the place of the map `path`, keeping the old one as
// `damaged` (its -wal too), so that a kill at any point leaves a map at `path`: the old one is
// linked (or, where the file system has no hard links, copied) to `damaged` first, then `fresh`
// replaces it in one rename.
Status SwapInRepairedMap(const std::string& path, const std::string& fresh,
                         const std::string& damaged) {
  std::error_code error;
  if (std::filesystem::exists(fresh + "-wal", error) &&
      std::filesystem::file_size(fresh + "-wal", error) > 0) {
    return Status::IoError("the repaired map " + fresh + " kept a write-ahead log; the map " +
                           path + " is unchanged");
  }
  if (!std::filesystem::equivalent(path, damaged, error)) {
    error.clear();
    std::filesystem::create_hard_link(path, damaged, error);
    if (error) {
      error.clear();
      std::filesystem::copy_file(path, damaged, error);
    }
    if (error) {
      return Status::IoError("cannot keep " + path + " as " + damaged + ": " + error.message() +
                             "; the map is unchanged");
    }
  }
  error.clear();
  if (std::filesystem::exists(path + "-wal", error)) {
    std::filesystem::copy_file(path + "-wal", damaged + "-wal",
                               std::filesystem::copy_options::overwrite_existing, error);
    if (error) {
      return Status::IoError("cannot keep " + path + "-wal as " + damaged +
                             "-wal: " + error.message() + "; the map is unchanged");
    }
  }
  // The old map's log and shared memory must not be read with the new file.
  for (const char* suffix : {"-wal", "-shm"}) {
    std::filesystem::remove(path + suffix, error);
    if (error) {
      return Status::IoError("cannot remove " + path + suffix + ": " + error.message() +
                             "; the map is unchanged");
    }
  }
  std::filesystem::remove(fresh + "-shm", error);
  error.clear();
  std::filesystem::rename(fresh, path, error);
  if (error) {
    return Status::IoError("cannot move " + fresh + " to " + path + ": " + error.message() +
                           " (the damaged map is still at " + path + ")");
  }
  return Status::Ok();
}

// OpenSqliteStore with options.read_only.
StatusOr<std::unique_ptr<LandmarkStore>> OpenReadOnlySqliteStore(
    const std::string& path, const SqliteStoreOptions& options) {
  if (path == ":memory:") {
    return Status::InvalidArgument("a map opened for reading only must be a file, not :memory:");
  }
  int version = 0;
  // Before the connection, as in OpenSqliteStore: closing a descriptor drops the process's locks.
  if (options.quick_check) ReadAhead(path, kReadAheadShare);
  StatusOr<SqliteConnection> db = OpenSqliteMapReadOnly(path, options.busy_timeout_ms, &version);
  if (!db.ok()) return db.status();
  if (options.quick_check) {
    const std::vector<std::string> problems = QuickCheck(db->get(), 5);
    if (!problems.empty()) {
      return Status::IoError("map " + path + " is damaged (SQLite quick_check: " +
                             Join(problems, 3) + "); " + kDamagedMapAdvice);
    }
  }
  return std::unique_ptr<LandmarkStore>(
      std::make_unique<SqliteStore>(path, std::move(db).value(), version));
}

}  // namespace

StatusOr<SqliteConnection> OpenSqliteMapReadOnly(const std::string& path, int busy_timeout_ms,
                                                 int* version) {
  std::error_code ignored;
  if (!std::filesystem::exists(path, ignored)) {
    return Status::NotFound("no placerec map at " + path);
  }
  StatusOr<SqliteConnection> opened =
      OpenSqliteDatabase(path, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX, busy_timeout_ms);
  if (!opened.ok()) return opened.status();
  SqliteConnection db = std::move(opened).value();
  StatusOr<int> read = ReadSchemaVersion(db.get(), path);
  if (!read.ok()) {
    // A map in WAL mode is read through its MAP-shm file, which SQLite creates beside it.
    const std::filesystem::path folder = std::filesystem::absolute(path).parent_path();
    if (access(folder.c_str(), W_OK | X_OK) != 0) {
      return Status::IoError(read.status().message() + "; SQLite reads a map through its -shm " +
                             "file, kept beside it, and cannot write in " + folder.string() +
                             ": copy the map (with its -wal file, if any) to a folder you can "
                             "write");
    }
    return read.status();
  }
  if (*read > kSqliteSchemaVersion) return NewerSchemaVersionError(path, *read);
  if (*read == 0) return Status::NotFound(path + " holds no placerec map (an empty database)");
  *version = *read;
  return StatusOr<SqliteConnection>(std::move(db));
}

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
  if (options.read_only) return OpenReadOnlySqliteStore(path, options);
  if (options.must_exist && path != ":memory:") {
    std::error_code ignored;
    if (!std::filesystem::exists(path, ignored)) {
      return Status::NotFound("no placerec map at " + path + " (it must exist)");
    }
  }
  // quick_check walks the file's trees page by page, a wait on the disk for each page that is not
  // cached; one pass in order brings them in at the disk's full speed (the map's load reads every
  // page next anyway). It comes before the connection: closing any descriptor of the file drops
  // every POSIX lock this process holds on it, SQLite's too, and without its lock on the map
  // another process's connection that closes takes itself for the last one and deletes the -wal
  // under this one.
  if (options.quick_check && path != ":memory:") ReadAhead(path, kReadAheadShare);
  StatusOr<SqliteConnection> db = OpenConnection(path, options);
  if (!db.ok()) return db.status();
  // SQLite falls back to reading a file it may not write; every frame's landmarks would then fail
  // to commit, so such a map is refused now. SQLite also keeps <map>-wal and <map>-shm beside it.
  if (sqlite3_db_readonly(db->get(), "main") == 1) {
    return Status::IoError("map " + path +
                           " cannot be written (a read-only file or file system): make it "
                           "writable (e.g. chmod u+w), or copy it to where it can be written");
  }
  if (path != ":memory:") {
    const std::filesystem::path parent = std::filesystem::absolute(path).parent_path();
    if (access(parent.c_str(), W_OK | X_OK) != 0) {
      return Status::IoError("the folder " + parent.string() + " of map " + path +
                             " cannot be written, but SQLite keeps the map's -wal and -shm "
                             "files there: make it writable, or move the map");
    }
  }

  // Refuse what is not ours before changing anything in the file.
  StatusOr<int> version = ReadSchemaVersion(db->get(), path);
  if (!version.ok()) return version.status();
  if (*version > kSqliteSchemaVersion) return NewerSchemaVersionError(path, *version);
  if (*version == 0 && options.must_exist) {
    return Status::NotFound(path + " holds no placerec map (an empty database)");
  }
  if (options.quick_check && *version > 0) {
    const std::vector<std::string> problems = QuickCheck(db->get(), 5);
    if (!problems.empty()) {
      return Status::IoError("map " + path + " is damaged (SQLite quick_check: " +
                             Join(problems, 3) + "); " + kDamagedMapAdvice);
    }
  }

  PLACEREC_RETURN_IF_ERROR(ConfigureConnection(db->get(), path, options));
  if (*version < kSqliteSchemaVersion) {
    PLACEREC_RETURN_IF_ERROR(MigrateSchemaToCurrent(db->get(), path));
  }

  SqliteStatement insert_place;
  SqliteStatement insert_landmark;
  int rc = SqliteStatement::Prepare(db->get(), kInsertPlace, true, &insert_place);
  if (rc == SQLITE_OK) {
    rc = SqliteStatement::Prepare(db->get(), kInsertLandmark, true, &insert_landmark);
  }
  if (rc != SQLITE_OK) {
    return Status::IoError("cannot prepare statements on " + path + ": " +
                           SqliteMessage(db->get(), rc));
  }
  return std::unique_ptr<LandmarkStore>(std::make_unique<SqliteStore>(
      path, std::move(db).value(), std::move(insert_place), std::move(insert_landmark)));
}

StatusOr<MapRepairReport> RepairSqliteMap(const std::string& path,
                                          const SqliteStoreOptions& options) {
  std::string error;
  if (!options.Check(&error)) return Status::InvalidArgument(error);
  if (path.empty() || path == ":memory:") {
    return Status::InvalidArgument("repair needs a map file, not '" + path + "'");
  }
  std::error_code ignored;
  if (!std::filesystem::exists(path, ignored)) {
    return Status::NotFound("no placerec map at " + path + " to repair");
  }
  MapRepairReport report;
  std::vector<WholePlace> kept;
  if (std::filesystem::exists(path + "-wal", ignored) &&
      std::filesystem::file_size(path + "-wal", ignored) > 0) {
    // Commits still in the WAL (a killed server) move into the file first, so that the pages
    // read from the file below are the current ones.
    StatusOr<SqliteConnection> db =
        OpenSqliteDatabase(path, SQLITE_OPEN_READWRITE, options.busy_timeout_ms);
    if (db.ok()) {
      sqlite3_exec(db->get(), "PRAGMA wal_checkpoint(TRUNCATE)", nullptr, nullptr, nullptr);
    }
  }
  // A log that could not be folded in would be lost with the swap below (the old map's log cannot
  // stay beside the new file).
  const StatusOr<bool> held = SqliteOpenElsewhere(path);
  if (std::filesystem::exists(path + "-wal", ignored) &&
      std::filesystem::file_size(path + "-wal", ignored) > 0 && held.ok() && !*held) {
    return Status::IoError("the write-ahead log " + path +
                           "-wal cannot be folded into the map; it cannot be repaired: copy " +
                           path + " and " + path + "-wal somewhere safe, then restore a backup");
  }
  // The file's pages that quick_check names are read directly, through a descriptor that outlives
  // the connection (see PlacesNamedByQuickCheck).
  std::ifstream file(path, std::ios::binary);
  {
    // Read-only: the damaged file is not changed by the reading.
    StatusOr<SqliteConnection> opened =
        OpenSqliteDatabase(path, SQLITE_OPEN_READONLY, options.busy_timeout_ms);
    if (!opened.ok()) return opened.status();
    const SqliteConnection db = std::move(opened).value();
    StatusOr<int> version = ReadSchemaVersion(db.get(), path);
    if (!version.ok()) {
      return Status::IoError(version.status().message() +
                             "; it cannot be repaired: restore it from a backup");
    }
    if (*version > kSqliteSchemaVersion) return NewerSchemaVersionError(path, *version);
    if (*version == 0) return Status::NotFound(path + " holds no placerec map to repair");
    const std::vector<std::string> problems = QuickCheck(db.get(), 1000);
    report.problems = Join(problems, 3);
    // Damage inside a BLOB's overflow pages reads back without an error; quick_check names the
    // cell whose chain is broken.
    const std::set<int64_t> named = PlacesNamedByQuickCheck(db.get(), file, problems);

    SqliteStatement max_id;
    int step = SqliteStatement::Prepare(db.get(), "SELECT COALESCE(MAX(id), 0) FROM places", false,
                                        &max_id);
    if (step == SQLITE_OK) step = max_id.Step();
    if (step != SQLITE_ROW) {
      return Status::IoError("map " + path + ": its places cannot be listed (" +
                             SqliteMessage(db.get(), step) +
                             "); it cannot be repaired: restore it from a backup");
    }
    const int64_t last = max_id.ColumnInt(0);
    constexpr int64_t kMaxPlaceId = 100000000;
    if (last < 0 || last > kMaxPlaceId) {
      return Status::IoError("map " + path + ": its largest place id " + std::to_string(last) +
                             " is not believable; it cannot be repaired: restore it from a backup");
    }
    const std::string store = "sqlite:" + path;
    int64_t unreadable_sightings = 0;  // kept places whose sightings do not read
    int64_t times_moved = 0;           // kept places whose time lay outside the range
    for (int64_t id = 1; id <= last; ++id) {
      WholePlace place;
      std::string why;
      const bool whole = ReadWholePlace(db.get(), *version, store, id, &place, &why);
      if (whole && named.count(id) > 0) {
        why = "place " + std::to_string(id) + " has a landmark in a damaged page";
      }
      if (whole && why.empty()) {
        if (place.sightings_unreadable && ++unreadable_sightings <= 3) {
          report.problems += (report.problems.empty() ? "" : "; ") + std::string("place ") +
                             std::to_string(id) + ": its sightings cannot be read";
        }
        if (place.stored_utime && ++times_moved <= 3) {
          report.notes += (report.notes.empty() ? "" : "; ") + std::string("place ") +
                          std::to_string(id) + ": capture time " +
                          std::to_string(*place.stored_utime) + " us, outside 0 .. " +
                          std::to_string(kMaxUtime) + ", is kept as " +
                          std::to_string(place.place.utime) + " (as the server uses it)";
        }
        place.place.thumbnail = ReadThumbnailForRepair(db.get(), *version, id);
        kept.push_back(std::move(place));
      } else if (!why.empty()) {
        ++report.places_dropped;
        if (report.places_dropped <= 3) {
          report.problems += (report.problems.empty() ? "" : "; ") + why;
        }
      }
    }
    if (times_moved > 3) {
      report.notes += "; in all " + std::to_string(times_moved) +
                      " places whose capture time lay outside the range";
    }
    if (unreadable_sightings > 3) {
      report.problems += "; in all " + std::to_string(unreadable_sightings) +
                         " places whose sightings cannot be read";
    }
  }
  file.close();  // after the connection
  for (const WholePlace& place : kept) {
    ++report.places_kept;
    report.landmarks_kept += static_cast<int64_t>(place.landmarks.size());
  }
  if (report.problems.empty() && report.places_dropped == 0) return report;  // whole: untouched

  // The rewrite moves the map's files: a server still writing would commit into the moved ones.
  const StatusOr<bool> elsewhere = SqliteOpenElsewhere(path);
  if (!elsewhere.ok()) return elsewhere.status();
  if (*elsewhere) {
    return Status::IoError("map " + path +
                           " is damaged and open in another process (a placerec-server, a "
                           "placerec-gateway with --db, a tool): stop it and repair the map again");
  }

  // Write the kept places to a new map beside the old one, then swap the files.
  const std::string fresh = path + ".repairing";
  for (const char* suffix : {"", "-wal", "-shm"}) std::filesystem::remove(fresh + suffix, ignored);
  {
    SqliteStoreOptions write = options;
    write.must_exist = false;
    StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(fresh, write);
    if (!store.ok()) return store.status();
    // Sightings follow their landmarks' new ids; one of a dropped place's landmarks goes.
    std::unordered_map<int64_t, LandmarkId> new_ids;
    for (WholePlace& place : kept) {
      place.place.id = PlaceId();
      std::vector<LandmarkId> seen;
      for (const LandmarkId old : place.place.seen_landmarks) {
        const auto found = new_ids.find(old.value());
        if (found != new_ids.end()) seen.push_back(found->second);
      }
      std::sort(seen.begin(), seen.end());
      seen.erase(std::unique(seen.begin(), seen.end()), seen.end());
      place.place.seen_landmarks = std::move(seen);
      std::vector<int64_t> old_ids;
      for (const Landmark& landmark : place.landmarks) old_ids.push_back(landmark.id.value());
      PLACEREC_RETURN_IF_ERROR((*store)->AddPlace(&place.place, &place.landmarks));
      for (size_t i = 0; i < old_ids.size(); ++i) new_ids[old_ids[i]] = place.landmarks[i].id;
    }
  }  // closed: the new map is one file again
  report.damaged_copy = path + ".damaged";
  if (!std::filesystem::equivalent(path, report.damaged_copy, ignored)) {
    // An earlier repair's copy goes; one that is this map's own link (a repair killed before its
    // swap) stays, as it is.
    for (const char* suffix : {"", "-wal", "-shm"}) {
      std::filesystem::remove(report.damaged_copy + suffix, ignored);
    }
  }
  PLACEREC_RETURN_IF_ERROR(SwapInRepairedMap(path, fresh, report.damaged_copy));
  report.rewritten = true;
  return report;
}

}  // namespace placerec
