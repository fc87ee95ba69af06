#include "tools/map_tools.h"

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <functional>
#include <iterator>
#include <memory>
#include <set>
#include <system_error>
#include <unordered_map>

#include "common/pipeline/place_map.h"
#include "common/recognition/types.h"
#include "common/storage/schema.h"
#include "common/storage/sqlite_db.h"
#include "common/storage/sqlite_store.h"
#include "common/util/paths.h"
#include "common/util/timer.h"
#include "proto/channels.h"

namespace placerec {
namespace {

// What a refusal of a map held open by another process says.
constexpr char kHeldOpenAdvice[] =
    " is open in another process (a running placerec-server?): stop the server and run the "
    "command again, or work on a copy of the map; info, export and check read a map while the "
    "server runs";

int64_t FileBytes(const std::string& path) {
  std::error_code error;
  const auto size = std::filesystem::file_size(path, error);
  return error ? 0 : static_cast<int64_t>(size);
}

// Opens the map at `path` for reading only (a running server may hold it) and reads its schema
// version (OpenSqliteMapReadOnly), saying where map files come from when there is none.
StatusOr<SqliteConnection> OpenReadOnly(const std::string& path, int* version) {
  std::error_code ignored;
  if (!std::filesystem::exists(path, ignored)) {
    return Status::NotFound("no placerec map at " + path +
                            ": give the map file a server or placerec-eval wrote (--db)");
  }
  return OpenSqliteMapReadOnly(path, /*busy_timeout_ms=*/2000, version);
}

// Runs `sql` and calls `row` for each result row; the error names `what` and `path`.
Status ForEachRow(sqlite3* db, const std::string& sql, const std::string& path,
                  const std::string& what, const std::function<void(SqliteStatement&)>& bind,
                  const std::function<void(const SqliteStatement&)>& row) {
  SqliteStatement select;
  int rc = SqliteStatement::Prepare(db, sql.c_str(), false, &select);
  if (rc == SQLITE_OK) {
    if (bind) bind(select);
    while ((rc = select.Step()) == SQLITE_ROW) row(select);
  }
  if (rc != SQLITE_DONE) {
    return Status::IoError("map " + path + ": cannot " + what + ": " + SqliteMessage(db, rc));
  }
  return Status::Ok();
}

std::string FormatUtime(int64_t utime) {
  const time_t seconds = static_cast<time_t>(utime / 1000000);
  std::tm tm{};
  gmtime_r(&seconds, &tm);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return text;
}

std::string FormatBytes(int64_t bytes) {
  char text[32];
  if (bytes >= (int64_t{1} << 20)) {
    std::snprintf(text, sizeof(text), "%.1f MiB", static_cast<double>(bytes) / (1 << 20));
  } else {
    std::snprintf(text, sizeof(text), "%.1f KiB", static_cast<double>(bytes) / 1024);
  }
  return text;
}

// The companions SQLite keeps beside a map file, by their suffix (the file itself: "").
constexpr const char* kMapFileSuffixes[] = {"", "-wal", "-shm", "-journal"};

// Removes `path` and its SQLite companions. Returns whether any of them was there.
bool RemoveMapFiles(const std::string& path) {
  bool any = false;
  for (const char* suffix : kMapFileSuffixes) {
    std::error_code ignored;
    if (std::filesystem::remove(path + suffix, ignored)) any = true;
  }
  return any;
}

// This machine's name, for work files: a process id means something on this machine only.
std::string HostName() {
  char name[256] = {};
  if (gethostname(name, sizeof(name) - 1) != 0 || name[0] == '\0') return "localhost";
  return name;
}

// The work file of the merge into `out` by process `pid` on machine `host`.
std::string MergeWorkFile(const std::string& out, const std::string& host, const std::string& pid) {
  return out + ".merging." + host + "." + pid;
}

// Removes `out`.merging.HOST.PID[-wal|-shm|-journal] of this machine for every PID that is no
// longer a running process: what a killed merge left. Another machine's files (a folder shared
// over the network) and the inputs `a` and `b` are never touched. Returns the removed work files.
std::vector<std::string> RemoveKilledMergesWork(const std::string& out, const std::string& a,
                                                const std::string& b) {
  const std::filesystem::path out_path(out);
  const std::filesystem::path dir =
      out_path.has_parent_path() ? out_path.parent_path() : std::filesystem::path(".");
  const std::string host = HostName();
  const std::string prefix = MergeWorkFile(out_path.filename().string(), host, "");
  std::set<std::string> stale;  // pids
  std::error_code error;
  for (std::filesystem::directory_iterator it(dir, error), end; !error && it != end;
       it.increment(error)) {
    const std::string name = it->path().filename().string();
    if (name.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string rest = name.substr(prefix.size());
    const size_t digits = rest.find_first_not_of("0123456789");
    const std::string pid_text = rest.substr(0, digits);
    // As std::to_string(getpid()) writes it: 1 to 9 digits, no leading zero.
    if (pid_text.empty() || pid_text.size() > 9 || pid_text[0] == '0') continue;
    const std::string suffix = digits == std::string::npos ? "" : rest.substr(digits);
    if (std::find(std::begin(kMapFileSuffixes), std::end(kMapFileSuffixes), suffix) ==
        std::end(kMapFileSuffixes)) {
      continue;
    }
    const pid_t pid = static_cast<pid_t>(std::stol(pid_text));
    // ESRCH: no such process. EPERM means it runs under another user: left alone.
    if (kill(pid, 0) != 0 && errno == ESRCH) stale.insert(pid_text);
  }
  std::vector<std::string> removed;
  for (const std::string& pid : stale) {
    const std::string path = MergeWorkFile(out, host, pid);
    bool is_input = false;
    for (const std::string& input : {a, b}) {
      std::error_code ignored;
      if (std::filesystem::equivalent(path, input, ignored)) is_input = true;
    }
    if (is_input) continue;
    if (RemoveMapFiles(path)) removed.push_back(path);
  }
  return removed;
}

}  // namespace

// ---- info -----------------------------------------------------------------------------------

nlohmann::json MapInfo::ToJson() const {
  nlohmann::json json;
  json["path"] = path;
  json["file_bytes"] = file_bytes;
  json["wal_bytes"] = wal_bytes;
  json["schema_version"] = schema_version;
  json["places"] = places;
  json["landmarks"] = landmarks;
  json["descriptors"] = descriptors;
  json["sightings"] = sightings;
  json["robots"] = nlohmann::json::array();
  for (const RobotInfo& robot : robots) {
    json["robots"].push_back({{"robot", robot.robot},
                              {"places", robot.places},
                              {"landmarks", robot.landmarks},
                              {"descriptors", robot.descriptors},
                              {"first_sequence", robot.first_sequence},
                              {"last_sequence", robot.last_sequence},
                              {"first_utime", robot.first_utime},
                              {"last_utime", robot.last_utime},
                              {"span_s", robot.SpanSeconds()}});
  }
  json["classes"] = nlohmann::json::array();
  for (const ClassInfo& item : classes) {
    json["classes"].push_back(
        {{"class",
          item.object_class.empty() ? nlohmann::json() : nlohmann::json(item.object_class)},
         {"landmarks", item.landmarks},
         {"descriptors", item.descriptors}});
  }
  return json;
}

std::string MapInfo::ToText() const {
  std::string text;
  char line[512];
  std::snprintf(line, sizeof(line), "map %s: schema version %d, %s", path.c_str(), schema_version,
                FormatBytes(file_bytes).c_str());
  text += line;
  if (wal_bytes > 0) text += " (+ " + FormatBytes(wal_bytes) + " not yet checkpointed in -wal)";
  std::snprintf(line, sizeof(line),
                "\n  %lld places, %lld landmarks, %lld descriptors, %lld sightings\n",
                static_cast<long long>(places), static_cast<long long>(landmarks),
                static_cast<long long>(descriptors), static_cast<long long>(sightings));
  text += line;
  text += "by robot:\n";
  for (const RobotInfo& robot : robots) {
    std::snprintf(
        line, sizeof(line),
        "  %-20s %6lld places %8lld landmarks %10lld descriptors  sequence %lld..%lld  "
        "%s .. %s (%.1f s)\n",
        robot.robot.c_str(), static_cast<long long>(robot.places),
        static_cast<long long>(robot.landmarks), static_cast<long long>(robot.descriptors),
        static_cast<long long>(robot.first_sequence), static_cast<long long>(robot.last_sequence),
        FormatUtime(robot.first_utime).c_str(), FormatUtime(robot.last_utime).c_str(),
        robot.SpanSeconds());
    text += line;
  }
  text += "by object class:\n";
  for (const ClassInfo& item : classes) {
    std::snprintf(line, sizeof(line), "  %-20s %8lld landmarks %10lld descriptors\n",
                  item.object_class.empty() ? "(unclassified)" : item.object_class.c_str(),
                  static_cast<long long>(item.landmarks), static_cast<long long>(item.descriptors));
    text += line;
  }
  return text;
}

StatusOr<MapInfo> ReadMapInfo(const std::string& path) {
  MapInfo info;
  info.path = path;
  StatusOr<SqliteConnection> db = OpenReadOnly(path, &info.schema_version);
  if (!db.ok()) return db.status();
  sqlite3* c = db->get();
  info.file_bytes = FileBytes(path);
  info.wal_bytes = FileBytes(path + "-wal");
  // One read transaction: every count from the same snapshot while a server writes.
  SqliteTransaction snapshot(c);
  const int rc = snapshot.Begin(/*immediate=*/false);
  if (rc != SQLITE_OK) return Status::IoError("map " + path + ": " + SqliteMessage(c, rc));
  const bool v2 = info.schema_version >= 2;
  PLACEREC_RETURN_IF_ERROR(ForEachRow(
      c,
      std::string("SELECT (SELECT COUNT(*) FROM places), (SELECT COUNT(*) FROM landmarks), "
                  "(SELECT COALESCE(SUM(num_descriptors), 0) FROM landmarks), ") +
          (v2 ? "(SELECT COUNT(*) FROM sightings)" : "0"),
      path, "count the map", nullptr, [&](const SqliteStatement& row) {
        info.places = row.ColumnInt(0);
        info.landmarks = row.ColumnInt(1);
        info.descriptors = row.ColumnInt(2);
        info.sightings = row.ColumnInt(3);
      }));
  PLACEREC_RETURN_IF_ERROR(ForEachRow(
      c,
      "SELECT robot, COUNT(*), MIN(sequence), MAX(sequence), MIN(utime), MAX(utime) FROM places "
      "GROUP BY robot ORDER BY robot",
      path, "list robots", nullptr, [&](const SqliteStatement& row) {
        RobotInfo robot;
        robot.robot = row.ColumnText(0);
        robot.places = row.ColumnInt(1);
        robot.first_sequence = row.ColumnInt(2);
        robot.last_sequence = row.ColumnInt(3);
        robot.first_utime = row.ColumnInt(4);
        robot.last_utime = row.ColumnInt(5);
        info.robots.push_back(robot);
      }));
  PLACEREC_RETURN_IF_ERROR(ForEachRow(
      c,
      "SELECT p.robot, COUNT(*), COALESCE(SUM(l.num_descriptors), 0) FROM landmarks l JOIN "
      "places p ON p.id = l.place_id GROUP BY p.robot",
      path, "count landmarks by robot", nullptr, [&](const SqliteStatement& row) {
        const std::string robot = row.ColumnText(0);
        for (RobotInfo& item : info.robots) {
          if (item.robot == robot) {
            item.landmarks = row.ColumnInt(1);
            item.descriptors = row.ColumnInt(2);
          }
        }
      }));
  PLACEREC_RETURN_IF_ERROR(ForEachRow(
      c,
      v2 ? "SELECT COALESCE(object_class, ''), COUNT(*), COALESCE(SUM(num_descriptors), 0) FROM "
           "landmarks GROUP BY 1 ORDER BY 1"
         : "SELECT '', COUNT(*), COALESCE(SUM(num_descriptors), 0) FROM landmarks",
      path, "count landmarks by class", nullptr, [&](const SqliteStatement& row) {
        if (row.ColumnInt(1) == 0) return;
        info.classes.push_back({row.ColumnText(0), row.ColumnInt(1), row.ColumnInt(2)});
      }));
  return info;
}

// ---- export ---------------------------------------------------------------------------------

StatusOr<std::vector<PlaceSummary>> ReadPlaceSummaries(const std::string& path) {
  int version = 0;
  StatusOr<SqliteConnection> db = OpenReadOnly(path, &version);
  if (!db.ok()) return db.status();
  sqlite3* c = db->get();
  SqliteTransaction snapshot(c);
  const int rc = snapshot.Begin(/*immediate=*/false);
  if (rc != SQLITE_OK) return Status::IoError("map " + path + ": " + SqliteMessage(c, rc));
  std::vector<PlaceSummary> places;
  std::unordered_map<int64_t, size_t> index;
  PLACEREC_RETURN_IF_ERROR(
      ForEachRow(c, "SELECT id, robot, sequence, utime FROM places ORDER BY id", path,
                 "list places", nullptr, [&](const SqliteStatement& row) {
                   PlaceSummary place;
                   place.id = row.ColumnInt(0);
                   place.robot = row.ColumnText(1);
                   place.sequence = row.ColumnInt(2);
                   place.utime = row.ColumnInt(3);
                   index[place.id] = places.size();
                   places.push_back(std::move(place));
                 }));
  PLACEREC_RETURN_IF_ERROR(ForEachRow(
      c,
      version >= 2 ? "SELECT place_id, COALESCE(object_class, ''), COUNT(*), "
                     "COALESCE(SUM(num_descriptors), 0) FROM landmarks GROUP BY 1, 2"
                   : "SELECT place_id, '', COUNT(*), COALESCE(SUM(num_descriptors), 0) FROM "
                     "landmarks GROUP BY 1",
      path, "count landmarks by place", nullptr, [&](const SqliteStatement& row) {
        const auto found = index.find(row.ColumnInt(0));
        if (found == index.end()) return;  // a landmark without its place: check reports it
        PlaceSummary& place = places[found->second];
        place.landmarks += row.ColumnInt(2);
        place.descriptors += row.ColumnInt(3);
        place.classes[row.ColumnText(1)] += row.ColumnInt(2);
      }));
  if (version >= 3) {
    PLACEREC_RETURN_IF_ERROR(ForEachRow(c, "SELECT place_id FROM thumbnails", path,
                                        "list thumbnails", nullptr,
                                        [&](const SqliteStatement& row) {
                                          const auto found = index.find(row.ColumnInt(0));
                                          if (found != index.end()) {
                                            places[found->second].thumbnail = true;
                                          }
                                        }));
  }
  return places;
}

Status ForEachThumbnail(const std::string& path,
                        const std::function<void(int64_t, const std::vector<uint8_t>&)>& visit) {
  int version = 0;
  StatusOr<SqliteConnection> db = OpenReadOnly(path, &version);
  if (!db.ok()) return db.status();
  if (version < 3) return Status::Ok();
  std::vector<uint8_t> bytes;
  return ForEachRow(db->get(), "SELECT place_id, jpeg FROM thumbnails ORDER BY place_id", path,
                    "read thumbnails", nullptr, [&](const SqliteStatement& row) {
                      const auto [data, size] = row.ColumnBlob(1);
                      bytes.assign(data, data + size);
                      visit(row.ColumnInt(0), bytes);
                    });
}

std::string FormatClassCounts(const std::map<std::string, int64_t>& classes) {
  std::string text;
  for (const auto& [name, count] : classes) {
    if (name.empty() || count == 0) continue;
    text += (text.empty() ? "" : ";") + name + ":" + std::to_string(count);
  }
  const auto unclassified = classes.find("");
  if (unclassified != classes.end() && unclassified->second > 0) {
    text += (text.empty() ? "" : ";") + std::string("unclassified:") +
            std::to_string(unclassified->second);
  }
  return text;
}

// ---- prune ----------------------------------------------------------------------------------

bool PruneOptions::Check(std::string* error) const {
  if (before_utime && *before_utime < 0) {
    *error = "--before must be a time after 1970";
    return false;
  }
  if (!before_utime && robot.empty()) {
    *error = "say what to drop: --before UTIME_OR_ISO_DATE, --robot ID, or both";
    return false;
  }
  if (busy_timeout_ms < 0) {
    *error = "busy_timeout_ms must be >= 0";
    return false;
  }
  return true;
}

StatusOr<int64_t> ParseTimeArgument(const std::string& text) {
  if (!text.empty() &&
      std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; })) {
    if (text.size() > 18) return Status::InvalidArgument("--before " + text + " is too large");
    return static_cast<int64_t>(std::stoll(text));
  }
  std::tm tm{};
  int consumed = 0;
  int year = 0, month = 0, day = 0, hour = 0, minute = 0, second = 0;
  const int fields = std::sscanf(text.c_str(), "%4d-%2d-%2d%n", &year, &month, &day, &consumed);
  bool ok = fields == 3;
  size_t at = static_cast<size_t>(consumed);
  if (ok && at < text.size()) {
    int more = 0;
    ok = (text[at] == 'T' || text[at] == ' ') &&
         std::sscanf(text.c_str() + at + 1, "%2d:%2d%n", &hour, &minute, &more) == 2;
    at += 1 + static_cast<size_t>(more);
    if (ok && at < text.size() && text[at] == ':') {
      more = 0;
      ok = std::sscanf(text.c_str() + at + 1, "%2d%n", &second, &more) == 1;
      at += 1 + static_cast<size_t>(more);
    }
    if (ok && at < text.size() && text[at] == 'Z') ++at;
    ok = ok && at == text.size();
  }
  // A day the month does not have (2011-02-29, 2011-04-31) is refused, not rolled over into the
  // next month.
  static constexpr int kDaysInMonth[12] = {31, 29, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  const bool leap = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
  ok = ok && month >= 1 && month <= 12 && day >= 1 && day <= kDaysInMonth[month - 1] &&
       (month != 2 || day <= 28 || leap) && hour >= 0 && hour < 24 && minute >= 0 && minute < 60 &&
       second >= 0 && second < 61 && year >= 1970;
  if (!ok) {
    return Status::InvalidArgument(
        "cannot read the time '" + text +
        "': give microseconds since the epoch (e.g. 1764576000000000) or an ISO date or UTC "
        "time (2026-12-01, 2026-12-01T08:30, 2026-12-01T08:30:15Z)");
  }
  tm.tm_year = year - 1900;
  tm.tm_mon = month - 1;
  tm.tm_mday = day;
  tm.tm_hour = hour;
  tm.tm_min = minute;
  tm.tm_sec = second;
  return static_cast<int64_t>(timegm(&tm)) * 1000000;
}

StatusOr<PruneReport> PruneMap(const std::string& path, const PruneOptions& options) {
  std::string error;
  if (!options.Check(&error)) return Status::InvalidArgument(error);
  std::error_code ignored;
  if (!std::filesystem::exists(path, ignored)) {
    return Status::NotFound("no placerec map at " + path);
  }
  // A server holding the map in another process locks its shared-memory file (and a shared lock
  // on the map file, which the exclusive lock below meets too): look there before opening the
  // map, and again once the lock is held (a server that opened it in between).
  const auto refuse_if_held = [&path]() -> Status {
    const StatusOr<bool> elsewhere = SqliteOpenElsewhere(path);
    if (!elsewhere.ok()) return elsewhere.status();
    return *elsewhere ? Status::IoError("map " + path + kHeldOpenAdvice) : Status::Ok();
  };
  if (!options.dry_run) PLACEREC_RETURN_IF_ERROR(refuse_if_held());
  StatusOr<SqliteConnection> opened =
      OpenSqliteDatabase(path, SQLITE_OPEN_READWRITE, options.busy_timeout_ms);
  if (!opened.ok()) return opened.status();
  const SqliteConnection db = std::move(opened).value();
  sqlite3* c = db.get();
  if (sqlite3_db_readonly(c, "main") == 1) {
    return Status::IoError("map " + path +
                           " cannot be written (a read-only file or folder): make it writable, or "
                           "prune a writable copy");
  }
  // Exclusive locking mode before the first access: the connection takes the file's exclusive
  // lock and keeps it until it closes, so a server that starts from now on cannot open the map.
  // A dry run only reads (one snapshot), and may run beside a server.
  if (!options.dry_run) {
    PLACEREC_RETURN_IF_ERROR(SqliteExec(c, "PRAGMA locking_mode = EXCLUSIVE", path));
  }
  PLACEREC_RETURN_IF_ERROR(SqliteExec(c, "PRAGMA foreign_keys = ON", path));
  int rc =
      sqlite3_exec(c, options.dry_run ? "BEGIN" : "BEGIN EXCLUSIVE", nullptr, nullptr, nullptr);
  if ((rc & 0xff) == SQLITE_BUSY || (rc & 0xff) == SQLITE_LOCKED) {
    return Status::IoError("map " + path + kHeldOpenAdvice);
  }
  if (rc != SQLITE_OK) {
    return Status::IoError("cannot lock map " + path + ": " + SqliteMessage(c, rc));
  }
  if (!options.dry_run) {
    const Status held = refuse_if_held();
    if (!held.ok()) {
      sqlite3_exec(c, "ROLLBACK", nullptr, nullptr, nullptr);
      // Closing, this connection must not checkpoint the other's write-ahead log and remove it.
      sqlite3_db_config(c, SQLITE_DBCONFIG_NO_CKPT_ON_CLOSE, 1, nullptr);
      return held;
    }
  }
  // Rolls back unless committed below; every exit before the commit leaves the map unchanged.
  struct Rollback {
    sqlite3* db;
    bool armed = true;
    ~Rollback() {
      if (armed) sqlite3_exec(db, "ROLLBACK", nullptr, nullptr, nullptr);
    }
  } rollback{c};

  StatusOr<int> version = ReadSchemaVersion(c, path);
  if (!version.ok()) return version.status();
  if (*version > kSqliteSchemaVersion) return NewerSchemaVersionError(path, *version);
  if (*version == 0) return Status::NotFound(path + " holds no placerec map (an empty database)");
  if (*version < kSqliteSchemaVersion) {
    return Status::IoError("map " + path + " has schema version " + std::to_string(*version) +
                           ": open it once with this build's placerec-server (which upgrades it "
                           "to version " +
                           std::to_string(kSqliteSchemaVersion) + "), then prune it");
  }

  PruneReport report;
  report.dry_run = options.dry_run;
  if (!options.robot.empty()) {
    // A misspelt robot would prune nothing and say so only as a count: name the map's robots.
    PLACEREC_RETURN_IF_ERROR(ForEachRow(
        c, "SELECT DISTINCT robot FROM places ORDER BY robot", path, "select robots", nullptr,
        [&](const SqliteStatement& row) { report.robots.push_back(row.ColumnText(0)); }));
    report.robot_unknown =
        std::find(report.robots.begin(), report.robots.end(), options.robot) == report.robots.end();
  }
  const std::string doomed =
      "SELECT id FROM places WHERE (?1 IS NULL OR utime < ?1) AND (?2 IS NULL OR robot = ?2)";
  const std::string doomed_landmarks =
      "SELECT id FROM landmarks WHERE place_id IN (" + doomed + ")";
  const auto bind = [&options](SqliteStatement& statement) {
    if (options.before_utime) {
      statement.BindInt(1, *options.before_utime);
    } else {
      statement.BindNull(1);
    }
    if (!options.robot.empty()) {
      statement.BindText(2, options.robot);
    } else {
      statement.BindNull(2);
    }
  };
  PLACEREC_RETURN_IF_ERROR(ForEachRow(
      c,
      "SELECT robot, COUNT(*) FROM places WHERE (?1 IS NULL OR utime < ?1) AND (?2 IS NULL OR "
      "robot = ?2) GROUP BY robot",
      path, "select places", bind, [&](const SqliteStatement& row) {
        report.places_by_robot[row.ColumnText(0)] = row.ColumnInt(1);
        report.places += row.ColumnInt(1);
      }));
  PLACEREC_RETURN_IF_ERROR(ForEachRow(
      c,
      "SELECT COUNT(*), COALESCE(SUM(num_descriptors), 0) FROM landmarks WHERE place_id IN (" +
          doomed + ")",
      path, "select landmarks", bind, [&](const SqliteStatement& row) {
        report.landmarks = row.ColumnInt(0);
        report.descriptors = row.ColumnInt(1);
      }));
  const std::string sightings_where = " FROM sightings WHERE place_id IN (" + doomed +
                                      ") OR landmark_id IN (" + doomed_landmarks + ")";
  PLACEREC_RETURN_IF_ERROR(
      ForEachRow(c, "SELECT COUNT(*)" + sightings_where, path, "select sightings", bind,
                 [&](const SqliteStatement& row) { report.sightings = row.ColumnInt(0); }));

  if (!options.dry_run && report.places > 0) {
    // Sightings and thumbnails first, then landmarks, then places: the foreign keys hold at
    // every step.
    const auto noop = [](const SqliteStatement&) {};
    PLACEREC_RETURN_IF_ERROR(
        ForEachRow(c, "DELETE" + sightings_where, path, "delete sightings", bind, noop));
    PLACEREC_RETURN_IF_ERROR(ForEachRow(c,
                                        "DELETE FROM thumbnails WHERE place_id IN (" + doomed + ")",
                                        path, "delete thumbnails", bind, noop));
    PLACEREC_RETURN_IF_ERROR(ForEachRow(c,
                                        "DELETE FROM landmarks WHERE place_id IN (" + doomed + ")",
                                        path, "delete landmarks", bind, noop));
    PLACEREC_RETURN_IF_ERROR(ForEachRow(
        c, "DELETE FROM places WHERE (?1 IS NULL OR utime < ?1) AND (?2 IS NULL OR robot = ?2)",
        path, "delete places", bind, noop));
    // What the server's next start relies on: nothing refers to a dropped row.
    int64_t dangling = 0;
    PLACEREC_RETURN_IF_ERROR(ForEachRow(c, "PRAGMA foreign_key_check", path, "check foreign keys",
                                        nullptr, [&](const SqliteStatement&) { ++dangling; }));
    if (dangling > 0) {
      return Status::IoError("map " + path + ": pruning would leave " + std::to_string(dangling) +
                             " rows referring to dropped ones; nothing was changed (run "
                             "placerec-map check on it)");
    }
  }
  PLACEREC_RETURN_IF_ERROR(ForEachRow(
      c, "SELECT (SELECT COUNT(*) FROM places), (SELECT COUNT(*) FROM landmarks)", path,
      "count the map", nullptr, [&](const SqliteStatement& row) {
        report.places_kept = row.ColumnInt(0) - (options.dry_run ? report.places : 0);
        report.landmarks_kept = row.ColumnInt(1) - (options.dry_run ? report.landmarks : 0);
      }));
  if (options.dry_run) return report;  // rolled back
  rc = sqlite3_exec(c, "COMMIT", nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK) {
    return Status::IoError("map " + path + ": cannot commit the pruning (nothing was changed): " +
                           SqliteMessage(c, rc));
  }
  rollback.armed = false;
  return report;
}

// ---- merge ----------------------------------------------------------------------------------

bool MergeOptions::Check(std::string* error) const {
  const bool valid = !suffix.empty() && std::all_of(suffix.begin(), suffix.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
           c == '-' || c == '.';
  });
  if (!valid) {
    *error =
        "--suffix must be 1 or more ASCII letters, digits, '_', '-' or '.' (robot id "
        "characters)";
    return false;
  }
  return true;
}

std::string MergedRobotId(const std::string& robot, const std::vector<std::string>& taken_in_a,
                          const std::vector<std::string>& taken, const std::string& suffix) {
  if (std::find(taken_in_a.begin(), taken_in_a.end(), robot) == taken_in_a.end()) return robot;
  for (int n = 1;; ++n) {
    const std::string name = robot + suffix + (n == 1 ? "" : std::to_string(n));
    if (std::find(taken.begin(), taken.end(), name) == taken.end()) return name;
  }
}

namespace {

// Copies every place of `from` (listed in `places`, id order) with its landmarks into `to`,
// streaming the landmarks (id order, grouped by place as AddPlace writes them). Robots are
// renamed by `rename`; sightings follow their landmarks' new ids.
Status CopyMap(const LandmarkStore& from, const std::string& from_path,
               const std::vector<Place>& places,
               const std::unordered_map<std::string, std::string>& rename, LandmarkStore* to,
               MergeInput* input) {
  int thumbnails_version = 0;
  StatusOr<SqliteConnection> thumbnails = OpenReadOnly(from_path, &thumbnails_version);
  if (!thumbnails.ok()) return thumbnails.status();
  std::unordered_map<int64_t, LandmarkId> new_ids;
  size_t next = 0;  // the first place not yet written
  bool have_current = false;
  size_t current = 0;
  std::vector<Landmark> pending;
  Status failed = Status::Ok();
  const auto write = [&](size_t i, std::vector<Landmark>* landmarks) -> Status {
    Place place = places[i];
    if (landmarks->size() != static_cast<size_t>(place.num_landmarks)) {
      return Status::IoError(from.Describe() + ": place " + std::to_string(place.id.value()) +
                             " lists " + std::to_string(place.num_landmarks) +
                             " landmarks but has " + std::to_string(landmarks->size()) +
                             "; run placerec-map check on it");
    }
    place.id = PlaceId();
    if (!CheckCaptureTime(place.utime).ok()) {
      place.utime = ClampCaptureTime(place.utime);
      ++input->times_moved;
    }
    const auto renamed = rename.find(place.robot);
    if (renamed != rename.end()) place.robot = renamed->second;
    std::vector<LandmarkId> seen;
    for (const LandmarkId old : place.seen_landmarks) {
      const auto found = new_ids.find(old.value());
      if (found == new_ids.end()) {
        return Status::IoError(from.Describe() + ": place " + std::to_string(places[i].id.value()) +
                               " saw landmark " + std::to_string(old.value()) +
                               ", which is not stored before it; run placerec-map check on it");
      }
      seen.push_back(found->second);
    }
    std::sort(seen.begin(), seen.end());
    // From a connection of its own: `from` is busy streaming the landmarks.
    if (thumbnails_version >= 3) {
      place.thumbnail.clear();
      PLACEREC_RETURN_IF_ERROR(ForEachRow(
          thumbnails->get(), "SELECT jpeg FROM thumbnails WHERE place_id = ?", from_path,
          "read a thumbnail",
          [&](SqliteStatement& select) { select.BindInt(1, places[i].id.value()); },
          [&](const SqliteStatement& row) {
            const auto [data, size] = row.ColumnBlob(0);
            place.thumbnail.assign(data, data + size);
          }));
    }
    input->sightings += static_cast<int64_t>(seen.size());
    place.seen_landmarks = std::move(seen);
    std::vector<int64_t> old_ids;
    for (const Landmark& landmark : *landmarks) old_ids.push_back(landmark.id.value());
    PLACEREC_RETURN_IF_ERROR(to->AddPlace(&place, landmarks));
    for (size_t k = 0; k < old_ids.size(); ++k) new_ids[old_ids[k]] = (*landmarks)[k].id;
    ++input->places;
    input->landmarks += static_cast<int64_t>(landmarks->size());
    for (const Landmark& landmark : *landmarks) input->descriptors += landmark.num_descriptors();
    return Status::Ok();
  };
  std::vector<Landmark> none;
  const auto flush_current = [&]() -> Status {
    if (!have_current) return Status::Ok();
    have_current = false;
    return write(current, &pending);
  };
  const int64_t last_place = places.empty() ? 0 : places.back().id.value();
  const Status loaded = from.LoadLandmarks([&](Landmark&& landmark) {
    if (!failed.ok()) return;
    const int64_t place = landmark.place.value();
    if (place > last_place) return;  // its place was added after the listing (a running server)
    if (have_current && places[current].id.value() == place) {
      pending.push_back(std::move(landmark));
      return;
    }
    failed = flush_current();
    while (failed.ok() && next < places.size() && places[next].id.value() < place) {
      none.clear();
      failed = write(next++, &none);
    }
    if (!failed.ok()) return;
    if (next < places.size() && places[next].id.value() == place) {
      current = next++;
      have_current = true;
      pending.clear();
      pending.push_back(std::move(landmark));
    } else {
      failed =
          Status::IoError(from.Describe() + ": landmark " + std::to_string(landmark.id.value()) +
                          " belongs to place " + std::to_string(place) +
                          ", which is missing or out of order; run placerec-map check on it");
    }
  });
  PLACEREC_RETURN_IF_ERROR(loaded);
  PLACEREC_RETURN_IF_ERROR(failed);
  PLACEREC_RETURN_IF_ERROR(flush_current());
  while (next < places.size()) {
    none.clear();
    PLACEREC_RETURN_IF_ERROR(write(next++, &none));
  }
  return Status::Ok();
}

}  // namespace

StatusOr<MergeReport> MergeMaps(const std::string& a, const std::string& b, const std::string& out,
                                const MergeOptions& options) {
  std::string error;
  if (!options.Check(&error)) return Status::InvalidArgument(error);
  if (out.empty()) return Status::InvalidArgument("merge needs --out FILE");
  std::error_code ignored;
  // symlink_status: a dangling link at `out` is a taken name too.
  if (std::filesystem::exists(std::filesystem::symlink_status(out, ignored))) {
    return Status::InvalidArgument(out +
                                   " exists: merge writes a new map; remove it or choose "
                                   "another --out");
  }
  // A log left by a killed writer of an earlier map of that name would be replayed onto the new
  // map by the next connection that opens it.
  for (const char* suffix : {"-wal", "-journal"}) {
    if (std::filesystem::exists(out + suffix, ignored)) {
      return Status::InvalidArgument(
          out + suffix + " exists (left by an earlier map " + out +
          "): SQLite would replay it onto the merged map; remove it (and " + out +
          "-shm) or choose another --out");
    }
  }
  SqliteStoreOptions read;
  read.read_only = true;  // the inputs stay as they are (an older schema is not upgraded)
  StatusOr<std::unique_ptr<LandmarkStore>> store_a = OpenSqliteStore(a, read);
  if (!store_a.ok()) return store_a.status();
  StatusOr<std::unique_ptr<LandmarkStore>> store_b = OpenSqliteStore(b, read);
  if (!store_b.ok()) return store_b.status();
  std::vector<Place> places_a, places_b;
  PLACEREC_RETURN_IF_ERROR(
      (*store_a)->LoadPlaces([&](const Place& place) { places_a.push_back(place); }));
  PLACEREC_RETURN_IF_ERROR(
      (*store_b)->LoadPlaces([&](const Place& place) { places_b.push_back(place); }));

  // B's robot ids, renamed where A has them too; refused before anything is written when a new
  // id would not fit a robot id on the wire.
  std::set<std::string> robots_a, robots_b;
  for (const Place& place : places_a) robots_a.insert(place.robot);
  for (const Place& place : places_b) robots_b.insert(place.robot);
  std::vector<std::string> taken_in_a(robots_a.begin(), robots_a.end());
  std::vector<std::string> taken = taken_in_a;
  taken.insert(taken.end(), robots_b.begin(), robots_b.end());
  MergeReport report;
  std::unordered_map<std::string, std::string> rename;
  for (const std::string& robot : robots_b) {
    const std::string name = MergedRobotId(robot, taken_in_a, taken, options.suffix);
    if (name == robot) continue;
    if (name.size() > kMaxWireRobotIdLength) {
      return Status::InvalidArgument(
          "robot '" + robot + "' is in both maps, and its new name in the merged map, '" + name +
          "', would have " + std::to_string(name.size()) + " bytes, over the " +
          std::to_string(kMaxWireRobotIdLength) +
          "-byte limit of robot ids; nothing was written. Give a shorter --suffix, or drop that "
          "robot from one map first (placerec-map prune --robot ID on a copy)");
    }
    taken.push_back(name);
    rename[robot] = name;
    report.renamed.emplace_back(robot, name);
  }

  // This process's own work file: another running merge into the same `out` is not touched (what
  // a killed one left is removed); of two merges racing for `out`, MoveWithoutReplacing below
  // lets only one in.
  const std::string temporary = MergeWorkFile(out, HostName(), std::to_string(getpid()));
  report.removed_work_files = RemoveKilledMergesWork(out, a, b);
  RemoveMapFiles(temporary);
  {
    SqliteStoreOptions write;
    write.synchronous_full = false;  // the file is synced when closed, before the rename
    write.quick_check = false;
    StatusOr<std::unique_ptr<LandmarkStore>> merged = OpenSqliteStore(temporary, write);
    if (!merged.ok()) return merged.status();
    report.a.path = a;
    report.b.path = b;
    Status copied = CopyMap(**store_a, a, places_a, {}, merged->get(), &report.a);
    if (copied.ok()) copied = CopyMap(**store_b, b, places_b, rename, merged->get(), &report.b);
    if (!copied.ok()) {
      merged->reset();
      RemoveMapFiles(temporary);
      return copied;
    }
  }  // closed: the last connection checkpoints the WAL into the file and removes it
  std::error_code wal_error;
  if (std::filesystem::exists(temporary + "-wal", wal_error) &&
      std::filesystem::file_size(temporary + "-wal", wal_error) > 0) {
    RemoveMapFiles(temporary);
    return Status::IoError("the merged map " + temporary +
                           " kept a write-ahead log when closed (its checkpoint failed); nothing "
                           "was written");
  }
  // Never replaces an existing file (another process may have created `out`).
  const Status moved = MoveWithoutReplacing(temporary, out);
  RemoveMapFiles(temporary);
  if (!moved.ok()) return Status::IoError(moved.message() + "; nothing was written");
  report.places = report.a.places + report.b.places;
  report.landmarks = report.a.landmarks + report.b.landmarks;
  return report;
}

// ---- check ----------------------------------------------------------------------------------

StatusOr<CheckReport> CheckMap(const std::string& path) {
  CheckReport report;
  {
    int version = 0;
    StatusOr<SqliteConnection> db = OpenReadOnly(path, &version);
    if (!db.ok()) return db.status();
    sqlite3* c = db->get();
    const Status integrity =
        ForEachRow(c, "PRAGMA integrity_check(100)", path, "run integrity_check", nullptr,
                   [&](const SqliteStatement& row) {
                     const std::string line = row.ColumnText(0);
                     if (line != "ok") report.problems.push_back("integrity_check: " + line);
                   });
    if (!integrity.ok()) report.problems.push_back(integrity.message());
    int dangling = 0;
    const Status keys = ForEachRow(c, "PRAGMA foreign_key_check", path, "check foreign keys",
                                   nullptr, [&](const SqliteStatement& row) {
                                     if (++dangling <= 10) {
                                       report.problems.push_back(row.ColumnText(0) + " row " +
                                                                 std::to_string(row.ColumnInt(1)) +
                                                                 " refers to a missing " +
                                                                 row.ColumnText(2) + " row");
                                     }
                                   });
    if (!keys.ok()) report.problems.push_back(keys.message());
    const Status counts = ForEachRow(
        c,
        "SELECT id, num_landmarks, n FROM (SELECT p.id, p.num_landmarks, (SELECT COUNT(*) FROM "
        "landmarks l WHERE l.place_id = p.id) AS n FROM places p) WHERE num_landmarks != n LIMIT "
        "10",
        path, "count landmarks per place", nullptr, [&](const SqliteStatement& row) {
          report.problems.push_back("place " + std::to_string(row.ColumnInt(0)) + " lists " +
                                    std::to_string(row.ColumnInt(1)) + " landmarks but has " +
                                    std::to_string(row.ColumnInt(2)));
        });
    if (!counts.ok()) report.problems.push_back(counts.message());
  }
  // Every place and landmark read back through the store: fields in range, BLOBs decoded.
  SqliteStoreOptions options;
  options.read_only = true;     // an older schema is read as it is, not upgraded
  options.quick_check = false;  // integrity_check above is the full version
  StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(path, options);
  if (!store.ok()) {
    report.problems.push_back("the store cannot open it: " + store.status().message());
    return report;
  }
  int64_t times_outside = 0;  // places whose capture time lies outside the range
  const Status places = (*store)->LoadPlaces([&](const Place& stored) {
    ++report.places;
    Place place = stored;
    if (!CheckCaptureTime(place.utime).ok()) {
      place.utime = ClampCaptureTime(place.utime);
      if (++times_outside <= 10) {
        report.notes.push_back("place " + std::to_string(place.id.value()) + ": capture time " +
                               std::to_string(stored.utime) + " us lies outside 0 .. " +
                               std::to_string(kMaxUtime) + "; the server uses " +
                               std::to_string(place.utime));
      }
    }
    const Status valid = place.Validate();
    if (!valid.ok()) {
      report.problems.push_back("place " + std::to_string(place.id.value()) + ": " +
                                valid.message());
    }
  });
  if (!places.ok()) report.problems.push_back(places.message());
  if (times_outside > 10) {
    report.notes.push_back("in all " + std::to_string(times_outside) +
                           " places whose capture time lies outside the range");
  }
  const Status landmarks = (*store)->LoadLandmarks([&](Landmark&& landmark) {
    ++report.landmarks;
    const Status valid = landmark.Validate();
    if (!valid.ok()) {
      report.problems.push_back("landmark " + std::to_string(landmark.id.value()) + ": " +
                                valid.message());
    }
  });
  if (!landmarks.ok()) report.problems.push_back(landmarks.message());
  return report;
}

StatusOr<IndexSnapshotReport> WriteIndexSnapshot(const std::string& path) {
  SqliteStoreOptions options;
  options.must_exist = true;
  Timer timer;
  StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(path, options);
  if (!store.ok()) return store.status();
  IndexSnapshotReport report;
  report.snapshot = (*store)->IndexSnapshotPath();
  // The tree depends on the descriptors and their order only, not on the search options.
  StatusOr<std::unique_ptr<PlaceMap>> map =
      PlaceMap::Open(std::move(*store), LandmarkIndexOptions());
  if (!map.ok()) return map.status();
  report.open_ms = timer.ElapsedMs();
  report.started_from_snapshot = (*map)->snapshot_load().used;
  report.descriptors = (*map)->Counts().descriptors;
  Timer write_timer;
  PLACEREC_RETURN_IF_ERROR((*map)->SaveIndexSnapshot(&report.written));
  report.write_ms = write_timer.ElapsedMs();
  if (!report.written && report.descriptors == 0) {
    // An emptied map (pruned to nothing): a snapshot of what it held is of no use.
    std::error_code ignored;
    report.removed_stale = std::filesystem::remove(report.snapshot, ignored);
  }
  return report;
}

}  // namespace placerec
