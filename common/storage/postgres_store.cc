#include "common/storage/postgres_store.h"

#include <libpq-fe.h>
#include <poll.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <climits>
#include <cstdint>
#include <cstring>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <system_error>
#include <unordered_map>
#include <utility>
#include <vector>

#include "common/features/features.h"
#include "common/storage/blob_codec.h"
#include "common/storage/checksum.h"
#include "common/storage/schema.h"
#include "common/util/logging.h"

namespace placerec {
namespace {

// Advisory lock keys (pg_advisory_xact_lock): kPostgresInsertLockKey serialises inserts; this one
// serialises schema creation by concurrent servers.
constexpr int64_t kSchemaLockKey = 0x706c6163736368;  // "placsch"

// SQLSTATEs the store tells apart.
constexpr char kUniqueViolation[] = "23505";
constexpr char kForeignKeyViolation[] = "23503";
constexpr char kLockNotAvailable[] = "55P03";  // lock_timeout
constexpr char kQueryCanceled[] = "57014";     // statement_timeout

// Schema v3 (schema.h) in PostgreSQL types: every integer BIGINT, BLOBs BYTEA (stored
// uncompressed: descriptors do not compress), the class confidence DOUBLE PRECISION.
constexpr char kCreateSchema[] = R"sql(
CREATE TABLE meta(
  key TEXT PRIMARY KEY,
  value TEXT);
CREATE TABLE places(
  id BIGSERIAL PRIMARY KEY,
  robot TEXT NOT NULL,
  sequence BIGINT NOT NULL,
  utime BIGINT NOT NULL,
  num_landmarks BIGINT NOT NULL,
  image_width BIGINT NOT NULL,
  UNIQUE(robot, sequence));
CREATE TABLE landmarks(
  id BIGSERIAL PRIMARY KEY,
  place_id BIGINT NOT NULL REFERENCES places(id),
  sift_count BIGINT,
  colour_peaks BYTEA,
  segment_class BIGINT,
  box_x BIGINT,
  box_y BIGINT,
  box_w BIGINT,
  box_h BIGINT,
  num_descriptors BIGINT,
  descriptors BYTEA,
  keypoints BYTEA,
  object_class TEXT,
  class_confidence DOUBLE PRECISION NOT NULL DEFAULT 0);
ALTER TABLE landmarks ALTER COLUMN descriptors SET STORAGE EXTERNAL;
ALTER TABLE landmarks ALTER COLUMN keypoints SET STORAGE EXTERNAL;
CREATE INDEX landmarks_place_id ON landmarks(place_id, num_descriptors);
CREATE TABLE sightings(
  place_id BIGINT NOT NULL REFERENCES places(id),
  landmark_id BIGINT NOT NULL REFERENCES landmarks(id),
  PRIMARY KEY(place_id, landmark_id));
CREATE TABLE thumbnails(
  place_id BIGINT PRIMARY KEY REFERENCES places(id),
  jpeg BYTEA NOT NULL);
)sql";
// Schema v2 -> v3 (schema.h): the place thumbnails; places of a v2 map have none.
constexpr char kMigrateV2ToV3[] = R"sql(
CREATE TABLE IF NOT EXISTS thumbnails(
  place_id BIGINT PRIMARY KEY REFERENCES places(id),
  jpeg BYTEA NOT NULL);
UPDATE meta SET value = '3' WHERE key = 'schema_version';
)sql";
constexpr char kInsertThumbnail[] = "INSERT INTO thumbnails(place_id, jpeg) VALUES($1, $2)";
constexpr char kSelectThumbnail[] = "SELECT jpeg FROM thumbnails WHERE place_id = $1";

// The columns of a place row, in the order ReadPlaceRow reads them.
#define PLACEREC_PLACE_COLUMNS "id, robot, sequence, utime, num_landmarks, image_width"
// The columns of a landmark row, in the order ReadLandmarkRow reads them.
#define PLACEREC_LANDMARK_COLUMNS                                                       \
  "id, place_id, sift_count, colour_peaks, segment_class, box_x, box_y, box_w, box_h, " \
  "num_descriptors, descriptors, keypoints, object_class, class_confidence"
constexpr char kInsertPlace[] =
    "INSERT INTO places(robot, sequence, utime, num_landmarks, image_width) "
    "VALUES($1, $2, $3, $4, $5) RETURNING id";
constexpr char kInsertSighting[] = "INSERT INTO sightings(place_id, landmark_id) VALUES($1, $2)";
constexpr char kInsertLandmark[] =
    "INSERT INTO landmarks(place_id, sift_count, colour_peaks, segment_class, box_x, box_y, box_w, "
    "box_h, num_descriptors, descriptors, keypoints, object_class, class_confidence) "
    "VALUES($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13) RETURNING id";
// Places, sightings and landmarks of the places with ids in ($1, $2].
constexpr char kSelectPlaces[] =
    "SELECT " PLACEREC_PLACE_COLUMNS " FROM places WHERE id > $1 AND id <= $2 ORDER BY id";
constexpr char kSelectSightings[] =
    "SELECT place_id, landmark_id FROM sightings WHERE place_id > $1 AND place_id <= $2 "
    "ORDER BY place_id, landmark_id";
constexpr char kSelectLandmarks[] = "SELECT " PLACEREC_LANDMARK_COLUMNS
                                    " FROM landmarks WHERE place_id > $1 AND place_id <= $2 "
                                    "ORDER BY id";
#undef PLACEREC_PLACE_COLUMNS
#undef PLACEREC_LANDMARK_COLUMNS

// What every refusal of a damaged row ends with.
constexpr char kDamagedMapAdvice[] =
    "restore the map from a backup (pg_dump / pg_restore of the placerec database)";

// Query parameters: integers and text as text, BYTEA as binary. The values stay valid while
// this object and the viewed bytes live.
class Params {
 public:
  void Int(int64_t value) { Text(std::to_string(value)); }
  void Text(std::string value) {
    storage_.push_back(std::move(value));
    values_.push_back(storage_.back().c_str());
    lengths_.push_back(0);
    formats_.push_back(0);
  }
  void Double(double value) {
    char buffer[64];
    const auto [end, error] = std::to_chars(buffer, buffer + sizeof(buffer), value);
    Text(error == std::errc() ? std::string(buffer, end) : std::string("0"));
  }
  void Bytes(ByteView bytes) {
    static const char kEmpty = 0;
    values_.push_back(bytes.data != nullptr ? reinterpret_cast<const char*>(bytes.data) : &kEmpty);
    lengths_.push_back(static_cast<int>(bytes.size));
    formats_.push_back(1);
  }
  void Null() {
    values_.push_back(nullptr);
    lengths_.push_back(0);
    formats_.push_back(0);
  }
  int size() const { return static_cast<int>(values_.size()); }
  const char* const* values() const { return values_.data(); }
  const int* lengths() const { return lengths_.data(); }
  const int* formats() const { return formats_.data(); }

 private:
  std::deque<std::string> storage_;  // a deque keeps the strings in place as it grows
  std::vector<const char*> values_;
  std::vector<int> lengths_;
  std::vector<int> formats_;
};

// A PGresult that is cleared when it goes out of scope.
class Result {
 public:
  explicit Result(PGresult* result = nullptr) : result_(result) {}
  Result(Result&& other) noexcept : result_(other.result_) { other.result_ = nullptr; }
  Result& operator=(Result&& other) noexcept {
    if (this != &other) {
      PQclear(result_);
      result_ = other.result_;
      other.result_ = nullptr;
    }
    return *this;
  }
  Result(const Result&) = delete;
  Result& operator=(const Result&) = delete;
  ~Result() { PQclear(result_); }
  PGresult* get() const { return result_; }
  ExecStatusType status() const { return PQresultStatus(result_); }
  std::string sqlstate() const {
    const char* state = PQresultErrorField(result_, PG_DIAG_SQLSTATE);
    return state != nullptr ? state : "";
  }
  int rows() const { return PQntuples(result_); }

 private:
  PGresult* result_;
};

// Reads binary result values (network byte order). A value of the wrong size or a NULL where a
// value must be reads as "missing".
bool ReadInt(const PGresult* result, int row, int column, int64_t low, int64_t high,
             int64_t* value) {
  if (PQgetisnull(result, row, column) || PQgetlength(result, row, column) != 8) return false;
  const auto* bytes = reinterpret_cast<const uint8_t*>(PQgetvalue(result, row, column));
  uint64_t bits = 0;
  for (int i = 0; i < 8; ++i) bits = (bits << 8) | bytes[i];
  *value = static_cast<int64_t>(bits);
  return *value >= low && *value <= high;
}

bool ReadDouble(const PGresult* result, int row, int column, double* value) {
  if (PQgetisnull(result, row, column) || PQgetlength(result, row, column) != 8) return false;
  const auto* bytes = reinterpret_cast<const uint8_t*>(PQgetvalue(result, row, column));
  uint64_t bits = 0;
  for (int i = 0; i < 8; ++i) bits = (bits << 8) | bytes[i];
  std::memcpy(value, &bits, sizeof(bits));
  return true;
}

std::string ReadText(const PGresult* result, int row, int column) {
  return std::string(PQgetvalue(result, row, column),
                     static_cast<size_t>(PQgetlength(result, row, column)));
}

ByteView ReadBytes(const PGresult* result, int row, int column) {
  if (PQgetisnull(result, row, column)) return {};
  const int size = PQgetlength(result, row, column);
  if (size == 0) return {};
  return {reinterpret_cast<const uint8_t*>(PQgetvalue(result, row, column)),
          static_cast<size_t>(size)};
}

// Reads and checks one place row (columns of kSelectPlaces).
Status ReadPlaceRow(const PGresult* result, int row, const std::string& store, Place* place) {
  int64_t id = 0;
  int64_t sequence = 0;
  int64_t utime = 0;
  int64_t num_landmarks = 0;
  int64_t image_width = 0;
  if (!ReadInt(result, row, 0, 1, INT64_MAX, &id) || PQgetisnull(result, row, 1) ||
      !ReadInt(result, row, 2, INT64_MIN, INT64_MAX, &sequence) ||
      !ReadInt(result, row, 3, INT64_MIN, INT64_MAX, &utime) ||
      !ReadInt(result, row, 4, 0, INT_MAX, &num_landmarks) ||
      !ReadInt(result, row, 5, 0, INT_MAX, &image_width)) {
    return Status::IoError(store + ": place " + std::to_string(id) +
                           " is corrupt: a field is missing or out of range; " + kDamagedMapAdvice);
  }
  *place = Place();
  place->id = PlaceId(id);
  place->robot = ReadText(result, row, 1);
  place->sequence = sequence;
  place->utime = utime;
  place->num_landmarks = static_cast<int>(num_landmarks);
  place->image_width = static_cast<int>(image_width);
  return Status::Ok();
}

// Reads and checks one landmark row (columns of kSelectLandmarks); its BLOBs point into `result`.
Status ReadLandmarkRow(const PGresult* result, int row, const std::string& store,
                       EncodedLandmark* out) {
  out->id = 0;
  const bool id_read = ReadInt(result, row, 0, 1, INT64_MAX, &out->id);
  const auto corrupt = [&](const std::string& what) {
    return Status::IoError(store + ": landmark " + std::to_string(out->id) +
                           " is corrupt: " + what + "; " + kDamagedMapAdvice);
  };
  if (!id_read) return corrupt("its id is missing or not positive");
  const struct {
    int column;
    const char* name;
    int64_t low, high;
    int64_t* value;
  } ints[] = {
      {1, "place_id", 0, INT64_MAX, &out->place},
      {2, "sift_count", 0, INT_MAX, &out->sift_count},
      {4, "segment_class", 0, 255, &out->segment_class},
      {5, "box_x", INT_MIN, INT_MAX, &out->box[0]},
      {6, "box_y", INT_MIN, INT_MAX, &out->box[1]},
      {7, "box_w", 0, INT_MAX, &out->box[2]},
      {8, "box_h", 0, INT_MAX, &out->box[3]},
      {9, "num_descriptors", 0, INT_MAX / kDescriptorSize, &out->num_descriptors},
  };
  for (const auto& field : ints) {
    if (!ReadInt(result, row, field.column, field.low, field.high, field.value)) {
      return corrupt(std::string(field.name) + " is missing or out of range");
    }
  }
  if (!IsKnownSegmentClass(out->segment_class)) {
    return corrupt("unknown segment_class " + std::to_string(out->segment_class));
  }
  out->object_class.clear();
  if (!PQgetisnull(result, row, 12)) out->object_class = ReadText(result, row, 12);
  double confidence = 0;
  if (!ReadDouble(result, row, 13, &confidence)) return corrupt("class_confidence is missing");
  out->class_confidence = static_cast<float>(confidence);
  {
    Landmark check;  // the class rules live in one place
    check.object_class = out->object_class;
    check.class_confidence = out->class_confidence;
    const Status valid = check.Validate();
    if (!valid.ok()) return corrupt(valid.message());
  }
  out->peaks = ReadBytes(result, row, 3);
  out->descriptors = ReadBytes(result, row, 10);
  out->keypoints = ReadBytes(result, row, 11);
  const Status blobs = CheckLandmarkBlobs(*out);
  if (!blobs.ok()) return corrupt(blobs.message());
  return Status::Ok();
}

// One libpq connection to the map's database. Not thread-safe; its owner serialises calls.
class Connection {
 public:
  Connection(std::string url, const PostgresStoreOptions& options)
      : url_(std::move(url)), options_(options) {}
  ~Connection() {
    if (conn_ != nullptr) PQfinish(conn_);
  }
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  const std::string& url() const { return url_; }
  const PostgresStoreOptions& options() const { return options_; }
  PGconn* get() const { return conn_; }

  // Connects when there is no good connection; IoError when the database cannot be reached.
  Status Ensure() {
    if (conn_ != nullptr && PQstatus(conn_) == CONNECTION_OK) return Status::Ok();
    if (conn_ != nullptr) {
      PQfinish(conn_);
      conn_ = nullptr;
    }
    const std::string timeout = std::to_string(options_.connect_timeout_s);
    // Over TCP, a database host that vanished without closing the connection (power loss, a cut
    // link) is noticed within about 30 s by TCP keepalives and the user timeout, instead of the
    // system's two hours: until then a follower would hear nothing and wait on a dead socket.
    // Before "dbname", so that the URL may set them otherwise; ignored on unix sockets.
    const char* keys[] = {"keepalives",       "keepalives_idle",  "keepalives_interval",
                          "keepalives_count", "tcp_user_timeout", "dbname",
                          "connect_timeout",  "application_name", nullptr};
    const char* values[] = {"1",        "10",   "5", "3", "30000", url_.c_str(), timeout.c_str(),
                            "placerec", nullptr};
    conn_ = PQconnectdbParams(keys, values, /*expand_dbname=*/1);
    if (conn_ == nullptr) return Status::IoError("postgres: out of memory connecting");
    if (PQstatus(conn_) != CONNECTION_OK) {
      const Status error = Error("cannot connect to the database");
      PQfinish(conn_);
      conn_ = nullptr;
      return error;
    }
    // Quiet NOTICEs (e.g. "relation already exists") instead of libpq printing them to stderr.
    PQsetNoticeProcessor(
        conn_, [](void*, const char*) {}, nullptr);
    return Status::Ok();
  }

  // Starts a transaction (`sql`: BEGIN and its options). A connection found broken here (e.g. the
  // database restarted since the last call) is opened again once, as nothing was sent yet.
  Status Begin(const char* sql) {
    PLACEREC_RETURN_IF_ERROR(Ensure());
    Status begun = Command(sql, "cannot start a transaction");
    if (begun.ok() || PQstatus(conn_) == CONNECTION_OK) return begun;
    PLACEREC_RETURN_IF_ERROR(Ensure());
    return Command(sql, "cannot start a transaction");
  }

  // Runs `sql` with `params`, results in binary.
  Result Exec(const char* sql, const Params& params = Params()) {
    return Result(PQexecParams(conn_, sql, params.size(), nullptr, params.values(),
                               params.lengths(), params.formats(), /*resultFormat=*/1));
  }

  // Runs commands without parameters or results (several may be given, separated by ';').
  Status Command(const char* sql, const std::string& what) {
    Result result(PQexec(conn_, sql));
    if (result.status() != PGRES_COMMAND_OK && result.status() != PGRES_TUPLES_OK) {
      return Error(what, result);
    }
    return Status::Ok();
  }

  // Streams the rows of `sql` one at a time (single-row mode: a large map is never held whole
  // in memory). `visit` gets a result holding one row; an error it returns stops the scan.
  Status Stream(const char* sql, const Params& params, const std::string& what,
                const std::function<Status(const PGresult*)>& visit) {
    if (!PQsendQueryParams(conn_, sql, params.size(), nullptr, params.values(), params.lengths(),
                           params.formats(), 1)) {
      return Error(what);
    }
    PQsetSingleRowMode(conn_);
    Status status;
    while (true) {
      Result result(PQgetResult(conn_));
      if (result.get() == nullptr) break;
      if (result.status() == PGRES_SINGLE_TUPLE) {
        if (status.ok()) status = visit(result.get());
      } else if (result.status() != PGRES_TUPLES_OK && status.ok()) {
        status = Error(what, result);
      }
    }
    return status;
  }

  // "postgres: WHAT: libpq's message" as an IoError.
  Status Error(const std::string& what, const Result& result) const {
    const char* message = PQresultErrorMessage(result.get());
    return Failure(what, message != nullptr && *message != '\0' ? message : PQerrorMessage(conn_));
  }
  Status Error(const std::string& what) const {
    return Failure(what, conn_ != nullptr ? PQerrorMessage(conn_) : "no connection");
  }

  // The URL without a password, for messages and Describe().
  std::string Describe() const { return Redacted(); }

 private:
  Status Failure(const std::string& what, std::string message) const {
    while (!message.empty() && (message.back() == '\n' || message.back() == ' ')) {
      message.pop_back();
    }
    for (char& c : message) {
      if (c == '\n') c = ' ';
    }
    return Status::IoError(Describe() + ": " + what + ": " + message);
  }
  // The URL without its passwords (postgresql://user:secret@host/... becomes
  // postgresql://user@host/..., and a password=... parameter password=***).
  std::string Redacted() const {
    std::string url = url_;
    const size_t scheme = url.find("://");
    const size_t at = url.find('@');
    if (scheme != std::string::npos && at != std::string::npos) {
      const size_t colon = url.find(':', scheme + 3);
      if (colon != std::string::npos && colon < at) url = url.substr(0, colon) + url.substr(at);
    }
    for (size_t p = url.find("password="); p != std::string::npos;
         p = url.find("password=", p + 1)) {
      if (p == 0 || (url[p - 1] != '?' && url[p - 1] != '&')) continue;
      const size_t end = url.find('&', p);
      url = url.substr(0, p) + "password=***" + (end == std::string::npos ? "" : url.substr(end));
    }
    return url;
  }

  const std::string url_;
  const PostgresStoreOptions options_;
  PGconn* conn_ = nullptr;
};

// Checks (and in an empty database creates) the schema, under an advisory lock so that servers
// starting together create it once.
Status PrepareSchema(Connection* db) {
  PLACEREC_RETURN_IF_ERROR(db->Command("BEGIN", "cannot start a transaction"));
  const auto fail = [db](Status status) {
    PQclear(PQexec(db->get(), "ROLLBACK"));
    return status;
  };
  Params lock;
  lock.Int(kSchemaLockKey);
  Result locked = db->Exec("SELECT pg_advisory_xact_lock($1)", lock);
  if (locked.status() != PGRES_TUPLES_OK) return fail(db->Error("cannot lock the schema", locked));
  Result tables = db->Exec(
      "SELECT COUNT(*), COUNT(*) FILTER (WHERE table_name = 'meta') FROM information_schema.tables "
      "WHERE table_schema = current_schema()");
  int64_t num_tables = 0;
  int64_t has_meta = 0;
  if (tables.status() != PGRES_TUPLES_OK || tables.rows() != 1 ||
      !ReadInt(tables.get(), 0, 0, 0, INT64_MAX, &num_tables) ||
      !ReadInt(tables.get(), 0, 1, 0, 1, &has_meta)) {
    return fail(db->Error("cannot list the tables", tables));
  }
  if (num_tables == 0) {
    PLACEREC_RETURN_IF_ERROR(db->Command(kCreateSchema, "cannot create the schema"));
    const std::string set = "INSERT INTO meta(key, value) VALUES('schema_version', '" +
                            std::to_string(kSqliteSchemaVersion) + "')";
    PLACEREC_RETURN_IF_ERROR(db->Command(set.c_str(), "cannot record the schema version"));
    PLACEREC_RETURN_IF_ERROR(db->Command("COMMIT", "cannot commit the schema"));
    LOG(INFO) << "created placerec map " << db->Describe() << " with schema version "
              << kSqliteSchemaVersion;
    return Status::Ok();
  }
  if (has_meta == 0) {
    return fail(Status::IoError(db->Describe() +
                                " is not a placerec map: the database holds tables but no meta "
                                "table; give placerec a database of its own"));
  }
  Result version = db->Exec("SELECT value FROM meta WHERE key = 'schema_version'");
  if (version.status() != PGRES_TUPLES_OK) {
    return fail(db->Error("cannot read the schema version", version));
  }
  if (version.rows() != 1 || PQgetisnull(version.get(), 0, 0)) {
    return fail(Status::IoError(db->Describe() +
                                " is not a placerec map: its meta table has no schema_version"));
  }
  const std::string text = ReadText(version.get(), 0, 0);
  int value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size() || value < 1) {
    return fail(Status::IoError(db->Describe() + " is not a placerec map: schema_version is '" +
                                text + "'"));
  }
  if (value > kSqliteSchemaVersion) return fail(NewerSchemaVersionError(db->Describe(), value));
  if (value == 2) {
    // A map of before the thumbnails: it gains their table, its places have none.
    PLACEREC_RETURN_IF_ERROR(db->Command(kMigrateV2ToV3, "cannot upgrade the schema to v3"));
    LOG(INFO) << "upgraded placerec map " << db->Describe() << " to schema version 3";
  } else if (value < kSqliteSchemaVersion) {
    // PostgreSQL maps began at version 2; an older number was not written by placerec.
    return fail(Status::IoError(db->Describe() + " has schema version " + std::to_string(value) +
                                ", which no placerec PostgreSQL map has"));
  }
  PLACEREC_RETURN_IF_ERROR(db->Command("COMMIT", "cannot end the transaction"));
  return Status::Ok();
}

// A row that does not read back whole (checked as ReadPlaceRow and ReadLandmarkRow check it),
// by the id of the place it belongs to.
using DamagedRow = std::function<void(int64_t place, const Status& why)>;

// Streams the places with ids in (after, up_to] with their sightings, in id order. A damaged row
// ends the scan with its error, or, given `damaged`, is reported there (its place is not visited)
// and the scan goes on.
Status ScanPlaces(Connection* db, int64_t after, int64_t up_to,
                  const std::function<void(Place&&)>& visit, const DamagedRow* damaged = nullptr) {
  Params range;
  range.Int(after);
  range.Int(up_to);
  std::unordered_map<int64_t, std::vector<LandmarkId>> seen;
  std::unordered_map<int64_t, Status> bad_sightings;
  PLACEREC_RETURN_IF_ERROR(
      db->Stream(kSelectSightings, range, "cannot read sightings", [&](const PGresult* row) {
        int64_t place = 0;
        int64_t landmark = 0;
        const bool place_read = ReadInt(row, 0, 0, 1, INT64_MAX, &place);
        if (!place_read || !ReadInt(row, 0, 1, 1, INT64_MAX, &landmark)) {
          const Status why =
              Status::IoError(db->Describe() + ": a sighting of place " + std::to_string(place) +
                              " is corrupt; " + kDamagedMapAdvice);
          if (damaged == nullptr || !place_read) return why;
          bad_sightings.emplace(place, why);
          return Status::Ok();
        }
        seen[place].push_back(LandmarkId(landmark));
        return Status::Ok();
      }));
  const std::string store = db->Describe();
  return db->Stream(kSelectPlaces, range, "cannot read places", [&](const PGresult* row) {
    Place place;
    const Status read = ReadPlaceRow(row, 0, store, &place);
    if (!read.ok()) {
      int64_t id = 0;
      if (damaged == nullptr || !ReadInt(row, 0, 0, 1, INT64_MAX, &id)) return read;
      (*damaged)(id, read);
      return Status::Ok();
    }
    if (const auto bad = bad_sightings.find(place.id.value()); bad != bad_sightings.end()) {
      (*damaged)(place.id.value(), bad->second);
      return Status::Ok();
    }
    const auto sightings = seen.find(place.id.value());
    if (sightings != seen.end()) place.seen_landmarks = std::move(sightings->second);
    visit(std::move(place));
    return Status::Ok();
  });
}

// Streams the checked landmark rows of the places with ids in (after, up_to], in id order. A
// damaged row ends the scan with its error, or, given `damaged`, is reported there and skipped.
Status ScanLandmarks(Connection* db, int64_t after, int64_t up_to,
                     const std::function<void(const EncodedLandmark&)>& visit,
                     const DamagedRow* damaged = nullptr) {
  Params range;
  range.Int(after);
  range.Int(up_to);
  const std::string store = db->Describe();
  EncodedLandmark encoded;
  return db->Stream(kSelectLandmarks, range, "cannot read landmarks", [&](const PGresult* row) {
    const Status read = ReadLandmarkRow(row, 0, store, &encoded);
    if (!read.ok()) {
      int64_t place = 0;
      if (damaged == nullptr || !ReadInt(row, 0, 1, 1, INT64_MAX, &place)) return read;
      (*damaged)(place, read);
      return Status::Ok();
    }
    visit(encoded);
    return Status::Ok();
  });
}

// ---------------------------------------------------------------------------------------------

class PostgresStore final : public LandmarkStore {
 public:
  explicit PostgresStore(std::unique_ptr<Connection> db) : db_(std::move(db)) {}

  Status AddPlace(Place* place, std::vector<Landmark>* landmarks) override;
  Status LoadPlaces(const std::function<void(const Place&)>& visit) const override;
  Status LoadLandmarks(const std::function<void(Landmark&&)>& visit) const override;
  StatusOr<std::vector<uint8_t>> LoadThumbnail(PlaceId place) const override;
  StatusOr<StoreCounts> Counts() const override;
  StatusOr<uint64_t> Checksum() const override;
  std::string Describe() const override { return db_->Describe(); }

 private:
  // Inserts the rows of a validated place inside the caller's transaction; the caller holds
  // mutex_.
  Status InsertRows(const Place& place, const std::vector<Landmark>& landmarks, int64_t* place_id,
                    std::vector<int64_t>* landmark_ids);

  // Serialises every call: a libpq connection serves one thread at a time.
  mutable std::mutex mutex_;
  std::unique_ptr<Connection> db_;
  // The largest place id the last LoadPlaces returned; LoadLandmarks stops there.
  mutable int64_t loaded_up_to_ = INT64_MAX;
  LandmarkBlobBuffers blob_buffers_;
};

Status PostgresStore::AddPlace(Place* place, std::vector<Landmark>* landmarks) {
  if (place == nullptr) return Status::InvalidArgument("AddPlace needs a place");
  static const std::vector<Landmark> kNoLandmarks;
  const std::vector<Landmark>& items = landmarks != nullptr ? *landmarks : kNoLandmarks;
  PLACEREC_RETURN_IF_ERROR(ValidatePlaceAndLandmarks(*place, items));

  std::lock_guard<std::mutex> lock(mutex_);
  int64_t place_id = 0;
  std::vector<int64_t> landmark_ids;
  landmark_ids.reserve(items.size());
  // The insert's timeouts go with its BEGIN, in the same round trip.
  const std::string timeout = std::to_string(db_->options().insert_timeout_ms);
  const std::string begin =
      "BEGIN; SET LOCAL lock_timeout = " + timeout + "; SET LOCAL statement_timeout = " + timeout;
  if (const Status begun = db_->Begin(begin.c_str()); !begun.ok()) {
    PQclear(PQexec(db_->get(), "ROLLBACK"));  // a BEGIN that went through, its SETs not
    return begun;
  }
  Status status = InsertRows(*place, items, &place_id, &landmark_ids);
  if (status.ok()) {
    Params notify;
    notify.Text(kPostgresPlacesChannel);
    notify.Text(std::to_string(place_id));
    Result sent = db_->Exec("SELECT pg_notify($1, $2)", notify);
    if (sent.status() != PGRES_TUPLES_OK) status = db_->Error("cannot notify the place", sent);
  }
  if (!status.ok()) {
    PQclear(PQexec(db_->get(), "ROLLBACK"));
    return status;
  }
  Result committed(PQexec(db_->get(), "COMMIT"));
  // COMMIT of a transaction that failed reports success with the tag ROLLBACK.
  if (committed.status() != PGRES_COMMAND_OK ||
      std::strcmp(PQcmdStatus(committed.get()), "COMMIT") != 0) {
    return db_->Error("cannot commit place", committed);
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

Status PostgresStore::InsertRows(const Place& place, const std::vector<Landmark>& landmarks,
                                 int64_t* place_id, std::vector<int64_t>* landmark_ids) {
  {
    Params lock;
    lock.Int(kPostgresInsertLockKey);
    Result locked = db_->Exec("SELECT pg_advisory_xact_lock($1)", lock);
    if (locked.status() != PGRES_TUPLES_OK) {
      const std::string state = locked.sqlstate();
      if (state == kLockNotAvailable || state == kQueryCanceled) {
        return db_->Error(
            "cannot lock the map for the insert (another server's insert holds the lock; one "
            "stopped or cut off inside it keeps it until PostgreSQL ends its session, which "
            "idle_in_transaction_session_timeout on the cluster bounds)",
            locked);
      }
      return db_->Error("cannot lock the map for the insert", locked);
    }
  }
  {
    Params row;
    row.Text(place.robot);
    row.Int(place.sequence);
    row.Int(place.utime);
    row.Int(static_cast<int64_t>(landmarks.size()));
    row.Int(place.image_width);
    Result inserted = db_->Exec(kInsertPlace, row);
    if (inserted.status() != PGRES_TUPLES_OK && inserted.sqlstate() == kUniqueViolation) {
      return Status::InvalidArgument("place robot/sequence already stored: robot '" + place.robot +
                                     "' sequence " + std::to_string(place.sequence));
    }
    if (inserted.status() != PGRES_TUPLES_OK || inserted.rows() != 1 ||
        !ReadInt(inserted.get(), 0, 0, 1, INT64_MAX, place_id)) {
      return db_->Error("cannot insert place", inserted);
    }
  }
  if (!place.thumbnail.empty()) {
    Params row;
    row.Int(*place_id);
    row.Bytes(ByteView{place.thumbnail.data(), place.thumbnail.size()});
    Result inserted = db_->Exec(kInsertThumbnail, row);
    if (inserted.status() != PGRES_COMMAND_OK) {
      return db_->Error("cannot insert thumbnail", inserted);
    }
  }
  for (const LandmarkId seen : place.seen_landmarks) {
    Params row;
    row.Int(*place_id);
    row.Int(seen.value());
    Result inserted = db_->Exec(kInsertSighting, row);
    if (inserted.status() != PGRES_COMMAND_OK && inserted.sqlstate() == kForeignKeyViolation) {
      return Status::InvalidArgument("place sees landmark " + std::to_string(seen.value()) +
                                     ", which is not in the map");
    }
    if (inserted.status() != PGRES_COMMAND_OK)
      return db_->Error("cannot insert sighting", inserted);
  }
  for (size_t i = 0; i < landmarks.size(); ++i) {
    const EncodedLandmark encoded = EncodeLandmark(landmarks[i], &blob_buffers_);
    Params row;
    row.Int(*place_id);
    row.Int(encoded.sift_count);
    row.Bytes(encoded.peaks);
    row.Int(encoded.segment_class);
    for (int k = 0; k < 4; ++k) row.Int(encoded.box[k]);
    row.Int(encoded.num_descriptors);
    row.Bytes(encoded.descriptors);
    row.Bytes(encoded.keypoints);
    if (encoded.object_class.empty()) {
      row.Null();
    } else {
      row.Text(encoded.object_class);
    }
    row.Double(encoded.class_confidence);
    Result inserted = db_->Exec(kInsertLandmark, row);
    int64_t id = 0;
    if (inserted.status() != PGRES_TUPLES_OK || inserted.rows() != 1 ||
        !ReadInt(inserted.get(), 0, 0, 1, INT64_MAX, &id)) {
      return db_->Error("cannot insert landmark " + std::to_string(i), inserted);
    }
    landmark_ids->push_back(id);
  }
  return Status::Ok();
}

Status PostgresStore::LoadPlaces(const std::function<void(const Place&)>& visit) const {
  std::lock_guard<std::mutex> lock(mutex_);
  PLACEREC_RETURN_IF_ERROR(db_->Begin("BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY"));
  int64_t last = 0;
  const Status status = ScanPlaces(db_.get(), 0, INT64_MAX, [&](Place&& place) {
    last = place.id.value();
    visit(place);
  });
  PQclear(PQexec(db_->get(), "COMMIT"));
  if (status.ok()) loaded_up_to_ = last;
  return status;
}

Status PostgresStore::LoadLandmarks(const std::function<void(Landmark&&)>& visit) const {
  std::lock_guard<std::mutex> lock(mutex_);
  PLACEREC_RETURN_IF_ERROR(db_->Ensure());
  return ScanLandmarks(db_.get(), 0, loaded_up_to_,
                       [&visit](const EncodedLandmark& row) { visit(DecodeLandmark(row)); });
}

StatusOr<std::vector<uint8_t>> PostgresStore::LoadThumbnail(PlaceId place) const {
  std::lock_guard<std::mutex> lock(mutex_);
  PLACEREC_RETURN_IF_ERROR(db_->Ensure());
  Params id;
  id.Int(place.value());
  Result found = db_->Exec(kSelectThumbnail, id);
  if (found.status() != PGRES_TUPLES_OK) return db_->Error("cannot read a thumbnail", found);
  if (found.rows() == 0) return std::vector<uint8_t>();
  const ByteView bytes = ReadBytes(found.get(), 0, 0);
  return std::vector<uint8_t>(bytes.data, bytes.data + bytes.size);
}

StatusOr<StoreCounts> PostgresStore::Counts() const {
  std::lock_guard<std::mutex> lock(mutex_);
  PLACEREC_RETURN_IF_ERROR(db_->Ensure());
  // One statement, so one consistent snapshot.
  Result counted = db_->Exec(
      "SELECT (SELECT COUNT(*) FROM places), COUNT(*), "
      "COALESCE(SUM(num_descriptors), 0)::BIGINT FROM landmarks");
  StoreCounts counts;
  if (counted.status() != PGRES_TUPLES_OK || counted.rows() != 1 ||
      !ReadInt(counted.get(), 0, 0, 0, INT64_MAX, &counts.places) ||
      !ReadInt(counted.get(), 0, 1, 0, INT64_MAX, &counts.landmarks) ||
      !ReadInt(counted.get(), 0, 2, 0, INT64_MAX, &counts.descriptors)) {
    return db_->Error("cannot count the map", counted);
  }
  return counts;
}

StatusOr<uint64_t> PostgresStore::Checksum() const {
  std::lock_guard<std::mutex> lock(mutex_);
  // Places and landmarks from one snapshot even while other servers insert.
  PLACEREC_RETURN_IF_ERROR(db_->Begin("BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY"));
  Fnv1a64 hash;
  Status status =
      ScanPlaces(db_.get(), 0, INT64_MAX, [&hash](Place&& place) { HashPlace(place, &hash); });
  if (status.ok()) {
    status = ScanLandmarks(db_.get(), 0, INT64_MAX,
                           [&hash](const EncodedLandmark& row) { HashLandmark(row, &hash); });
  }
  PQclear(PQexec(db_->get(), "COMMIT"));
  if (!status.ok()) return status;
  return hash.digest();
}

// ---------------------------------------------------------------------------------------------

class ChangeFeed final : public PostgresChangeFeed {
 public:
  explicit ChangeFeed(std::unique_ptr<Connection> db) : db_(std::move(db)) {}

  StatusOr<int> Wait(int timeout_ms) override {
    const int fd = PQsocket(db_->get());
    if (fd < 0 || PQstatus(db_->get()) != CONNECTION_OK)
      return db_->Error("the connection is lost");
    int arrived = Drain();
    if (arrived > 0) return arrived;
    pollfd wait = {fd, POLLIN, 0};
    const int ready = poll(&wait, 1, timeout_ms);
    if (ready < 0 && errno != EINTR) return Status::IoError(db_->Describe() + ": poll failed");
    if (ready > 0) {
      if (!PQconsumeInput(db_->get()) || PQstatus(db_->get()) != CONNECTION_OK) {
        return db_->Error("the connection is lost");
      }
      arrived = Drain();
    }
    return arrived;
  }

  StatusOr<std::vector<CommittedPlace>> FetchAfter(PlaceId after, int max_places) override {
    if (PQstatus(db_->get()) != CONNECTION_OK) return db_->Error("the connection is lost");
    PLACEREC_RETURN_IF_ERROR(db_->Command("BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY",
                                          "cannot start a read transaction"));
    std::vector<CommittedPlace> places;
    Status status = Fetch(after.value(), max_places, &places);
    PQclear(PQexec(db_->get(), "COMMIT"));
    if (!status.ok()) return status;
    return places;
  }

 private:
  // Consumes the notifications already read; how many there were.
  int Drain() {
    int count = 0;
    while (PGnotify* notify = PQnotifies(db_->get())) {
      ++count;
      PQfreemem(notify);
    }
    return count;
  }

  Status Fetch(int64_t after, int max_places, std::vector<CommittedPlace>* places) {
    // The upper end of this batch: the max_places-th place above `after`.
    Params range;
    range.Int(after);
    range.Int(max_places);
    Result last = db_->Exec(
        "SELECT MAX(id) FROM (SELECT id FROM places WHERE id > $1 ORDER BY id LIMIT $2) AS batch",
        range);
    if (last.status() != PGRES_TUPLES_OK || last.rows() != 1) {
      return db_->Error("cannot read new places", last);
    }
    if (PQgetisnull(last.get(), 0, 0)) return Status::Ok();  // nothing new
    int64_t up_to = 0;
    if (!ReadInt(last.get(), 0, 0, 1, INT64_MAX, &up_to)) {
      return db_->Error("cannot read new places", last);
    }
    // A damaged place is handed on marked as such (without landmarks), so that a follower can
    // go on past it; the first damage found names it.
    std::map<int64_t, Status> damage;
    const DamagedRow damaged = [&damage](int64_t place, const Status& why) {
      damage.emplace(place, why);
    };
    std::unordered_map<int64_t, size_t> slot;
    PLACEREC_RETURN_IF_ERROR(ScanPlaces(
        db_.get(), after, up_to,
        [&](Place&& place) {
          slot[place.id.value()] = places->size();
          places->push_back({std::move(place), {}, Status::Ok()});
        },
        &damaged));
    Status status;
    PLACEREC_RETURN_IF_ERROR(ScanLandmarks(
        db_.get(), after, up_to,
        [&](const EncodedLandmark& row) {
          const auto it = slot.find(row.place);
          if (it == slot.end()) {
            // Its place row is damaged (reported), or missing.
            if (damage.count(row.place) == 0 && status.ok()) {
              status = Status::IoError(db_->Describe() + ": landmark " + std::to_string(row.id) +
                                       " refers to missing place " + std::to_string(row.place));
            }
            return;
          }
          (*places)[it->second].landmarks.push_back(DecodeLandmark(row));
        },
        &damaged));
    if (!status.ok()) return status;
    if (damage.empty()) return Status::Ok();
    // The damaged places, each without landmarks, in id order among the others.
    for (const auto& [id, why] : damage) {
      const auto it = slot.find(id);
      CommittedPlace* lost = nullptr;
      if (it != slot.end()) {
        lost = &(*places)[it->second];
      } else {
        lost = &places->emplace_back();
        lost->place.id = PlaceId(id);
      }
      lost->landmarks.clear();
      lost->damage = why;
    }
    std::sort(places->begin(), places->end(), [](const CommittedPlace& a, const CommittedPlace& b) {
      return a.place.id < b.place.id;
    });
    return Status::Ok();
  }

  std::unique_ptr<Connection> db_;
};

}  // namespace

bool PostgresStoreOptions::Check(std::string* error) const {
  if (connect_timeout_s < 1 || connect_timeout_s > 3600) {
    *error = "postgres connect_timeout_s must be between 1 and 3600 seconds";
    return false;
  }
  if (insert_timeout_ms < 1 || insert_timeout_ms > 3600000) {
    *error = "postgres insert_timeout_ms must be between 1 and 3600000 milliseconds";
    return false;
  }
  return true;
}

bool IsPostgresUrl(const std::string& db) {
  return db.rfind("postgresql://", 0) == 0 || db.rfind("postgres://", 0) == 0;
}

StatusOr<std::unique_ptr<LandmarkStore>> OpenPostgresStore(const std::string& url,
                                                           const PostgresStoreOptions& options) {
  std::string error;
  if (!options.Check(&error)) return Status::InvalidArgument(error);
  if (!IsPostgresUrl(url)) {
    return Status::InvalidArgument(
        "'" + url + "' is not a PostgreSQL URL (postgresql://... or postgres://...)");
  }
  auto db = std::make_unique<Connection>(url, options);
  PLACEREC_RETURN_IF_ERROR(db->Ensure());
  PLACEREC_RETURN_IF_ERROR(PrepareSchema(db.get()));
  return std::unique_ptr<LandmarkStore>(std::make_unique<PostgresStore>(std::move(db)));
}

StatusOr<std::unique_ptr<PostgresChangeFeed>> PostgresChangeFeed::Open(
    const std::string& url, const PostgresStoreOptions& options) {
  std::string error;
  if (!options.Check(&error)) return Status::InvalidArgument(error);
  if (!IsPostgresUrl(url)) {
    return Status::InvalidArgument("'" + url + "' is not a PostgreSQL URL");
  }
  auto db = std::make_unique<Connection>(url, options);
  PLACEREC_RETURN_IF_ERROR(db->Ensure());
  const std::string listen = std::string("LISTEN ") + kPostgresPlacesChannel;
  PLACEREC_RETURN_IF_ERROR(db->Command(listen.c_str(), "cannot listen for new places"));
  return std::unique_ptr<PostgresChangeFeed>(std::make_unique<ChangeFeed>(std::move(db)));
}

}  // namespace placerec
