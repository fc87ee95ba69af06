// The map tools of `placerec-map` (issue 22 item 5): look at, export, prune, merge and check a
// SQLite landmark map (common/storage) without a running server. Commands that only read (info,
// export, check, and the inputs of merge) work while a server has the map open; commands that
// write (prune) take SQLite's exclusive lock first and refuse a map another process holds open,
// so a running server never sees its map change under it. Writing is all-or-nothing: prune runs
// in one transaction, merge writes a temporary file and renames it into place.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/util/status.h"

namespace placerec {

// ---- info -----------------------------------------------------------------------------------

struct RobotInfo {
  std::string robot;
  int64_t places = 0;
  int64_t landmarks = 0;
  int64_t descriptors = 0;
  int64_t first_sequence = 0, last_sequence = 0;
  int64_t first_utime = 0, last_utime = 0;  // microseconds since the epoch
  // From the first to the last capture time, in seconds (in floating point: a map may hold
  // times outside the range whose difference overflows 64 bits).
  double SpanSeconds() const {
    return (static_cast<double>(last_utime) - static_cast<double>(first_utime)) / 1e6;
  }
};

struct ClassInfo {
  std::string object_class;  // empty: unclassified
  int64_t landmarks = 0;
  int64_t descriptors = 0;
};

struct MapInfo {
  std::string path;
  int64_t file_bytes = 0;  // the map file
  int64_t wal_bytes = 0;   // its -wal companion (commits not yet checkpointed), 0 when absent
  int schema_version = 0;
  int64_t places = 0;
  int64_t landmarks = 0;
  int64_t descriptors = 0;
  int64_t sightings = 0;
  std::vector<RobotInfo> robots;   // by robot id
  std::vector<ClassInfo> classes;  // by class name, unclassified first

  nlohmann::json ToJson() const;
  std::string ToText() const;
};

// Reads the counts of the map at `path` through a read-only connection (works while a server
// runs). NotFound for a missing file, IoError for a file that is not a placerec map or is newer.
StatusOr<MapInfo> ReadMapInfo(const std::string& path);

// ---- export ---------------------------------------------------------------------------------

// One place of the map with its landmark counts.
struct PlaceSummary {
  int64_t id = 0;
  std::string robot;
  int64_t sequence = 0;
  int64_t utime = 0;
  int64_t landmarks = 0;
  int64_t descriptors = 0;
  std::map<std::string, int64_t> classes;  // object class -> landmarks; "" for unclassified
  bool thumbnail = false;                  // the place keeps a thumbnail (schema v3)
};

// Calls `visit` with every stored place thumbnail (place id, JPEG bytes) in id order, read-only;
// nothing for maps before schema v3.
Status ForEachThumbnail(const std::string& path,
                        const std::function<void(int64_t, const std::vector<uint8_t>&)>& visit);

// Every place of the map, in id order (read-only, like ReadMapInfo).
StatusOr<std::vector<PlaceSummary>> ReadPlaceSummaries(const std::string& path);

// "building:3;sign:1": the classified landmarks by class name, unclassified ones last as
// "unclassified:N"; empty for a place without landmarks.
std::string FormatClassCounts(const std::map<std::string, int64_t>& classes);

struct ExportReport {
  int64_t places = 0;
  int64_t robots = 0;
  std::string csv_path;
  std::string picture_path;
  int64_t thumbnails = 0;          // thumbnails written to out_dir/thumbnails/<id>.jpg
  std::string contact_sheet_path;  // empty when the map has no thumbnails
};

// Writes out_dir/places.csv (id,robot,sequence,utime,landmarks,descriptors,classes,thumbnail:
// the thumbnail's file relative to out_dir, empty without one), out_dir/route.png (per robot a
// timeline strip of its places coloured by landmark count, a strip of their class shares, and the
// robot's class counts), the place thumbnails as out_dir/thumbnails/<id>.jpg and, when there are
// any, out_dir/contact_sheet.jpg (at most 120 of them, evenly spread over the route, in id order,
// each labelled robot #sequence). Creates out_dir.
StatusOr<ExportReport> ExportMap(const std::string& path, const std::string& out_dir);

// ---- prune ----------------------------------------------------------------------------------

struct PruneOptions {
  // Drop places captured before this time (microseconds since the epoch); none: no time limit
  // (a time of 0 is a limit: it drops nothing).
  std::optional<int64_t> before_utime;
  // Drop the places of this robot; empty: every robot. With before_utime too, only that robot's
  // places before the time.
  std::string robot;
  // Count what would be dropped, change nothing; reads only, so it may run beside a server.
  bool dry_run = false;
  // How long to wait for another connection's lock before refusing the map (milliseconds).
  int busy_timeout_ms = 200;

  bool Check(std::string* error) const;
};

struct PruneReport {
  bool dry_run = false;
  int64_t places = 0;       // places dropped (or that would be)
  int64_t landmarks = 0;    // their landmarks
  int64_t descriptors = 0;  // those landmarks' descriptors
  int64_t sightings = 0;    // sightings by the dropped places or of their landmarks
  std::map<std::string, int64_t> places_by_robot;
  int64_t places_kept = 0;
  int64_t landmarks_kept = 0;
  // PruneOptions::robot names no robot of the map (a misspelt id, or one pruned before): the
  // map's robots, for the message. Nothing was pruned.
  bool robot_unknown = false;
  std::vector<std::string> robots;
};

// Drops the places options select, their landmarks, and the sightings by them or of their
// landmarks, in one exclusive transaction: on any error the map is unchanged. Refuses (IoError)
// a map another process holds open, e.g. a running server.
StatusOr<PruneReport> PruneMap(const std::string& path, const PruneOptions& options);

// A time for --before: microseconds since the epoch (digits only), or an ISO 8601 date or UTC
// time: 2026-12-01, 2026-12-01T08:30, 2026-12-01T08:30:15 or 2026-12-01T08:30:15Z.
StatusOr<int64_t> ParseTimeArgument(const std::string& text);

// ---- merge ----------------------------------------------------------------------------------

struct MergeOptions {
  // A robot id of the second map that the first map also has gets this suffix (then suffix + 2,
  // suffix + 3, ... while the name is taken in either map). Letters, digits, '_', '-', '.': the
  // characters a robot id may have on the wire (proto/README.md).
  std::string suffix = ".b";

  bool Check(std::string* error) const;
};

struct MergeInput {
  std::string path;
  int64_t places = 0;
  int64_t landmarks = 0;
  int64_t descriptors = 0;
  int64_t sightings = 0;
  // Places whose capture time lay outside 0 .. kMaxUtime, written with the time the server
  // serves them with (ClampCaptureTime), as the repair keeps them.
  int64_t times_moved = 0;
};

struct MergeReport {
  MergeInput a, b;
  std::vector<std::pair<std::string, std::string>> renamed;  // B's robot id -> its id in C
  int64_t places = 0;
  int64_t landmarks = 0;
  // Work files of earlier merges into `out` whose process is gone (killed), removed.
  std::vector<std::string> removed_work_files;
};

// Writes a new map `out` holding first every place of `a`, then every place of `b` (in id order,
// with new ids; sightings follow their landmarks' new ids), B's colliding robot ids renamed by
// MergeOptions::suffix. Refuses, before writing anything, an existing `out` and a renamed id
// longer than the 47-byte wire limit of robot ids. The map is written to `out`.merging.HOST.PID
// and moved to `out` when complete, never replacing a file (MoveWithoutReplacing); on error
// nothing is left behind (on a file system without hard links or RENAME_NOREPLACE, a merge killed
// within the move's two steps leaves an empty `out`). What a killed merge left
// (`out`.merging.HOST.PID of this machine whose process no longer runs) is removed first; a running
// merge's work file, another machine's and an input are left alone.
StatusOr<MergeReport> MergeMaps(const std::string& a, const std::string& b, const std::string& out,
                                const MergeOptions& options);

// The id B's robot `robot` gets in the merged map: itself when `taken_in_a` lacks it, otherwise
// robot + suffix, robot + suffix + "2", ... whichever is first free in both maps' ids `taken`.
std::string MergedRobotId(const std::string& robot, const std::vector<std::string>& taken_in_a,
                          const std::vector<std::string>& taken, const std::string& suffix);

// ---- check ----------------------------------------------------------------------------------

struct CheckReport {
  std::vector<std::string> problems;  // empty: the map is whole
  // What is no damage but not as this build writes it (a capture time outside the range, which
  // the server serves as the nearest end of the range).
  std::vector<std::string> notes;
  int64_t places = 0;     // places read back
  int64_t landmarks = 0;  // landmarks read back whole
  bool ok() const { return problems.empty(); }
};

// The full check: SQLite's integrity_check, foreign keys (every landmark's place and every
// sighting's place and landmark exist), each place's landmark count, then every place and
// landmark read back through the store (the BLOB encodings decoded and validated). An error
// status only when the check itself cannot run; damage goes into the report.
StatusOr<CheckReport> CheckMap(const std::string& path);

struct IndexSnapshotReport {
  std::string snapshot;                // the file written (MAP.index)
  bool written = false;                // false: the snapshot on disk already covered the whole map
  bool removed_stale = false;          // the map holds no descriptors: a snapshot was removed
  bool started_from_snapshot = false;  // the map opened from an older snapshot
  int64_t descriptors = 0;             // descriptors the snapshot covers
  double open_ms = 0;                  // opening the map (PlaceMap::Open)
  double write_ms = 0;                 // writing the snapshot
};

// Opens the map as the server does (must exist; from its descriptor index snapshot when one
// fits) and writes the snapshot beside it, so that the next server start loads the FLANN tree
// instead of growing it point by point. Opens the map as the server does (upgrading an older
// schema); a place committed while it reads can make it fail ("refers to missing place").
StatusOr<IndexSnapshotReport> WriteIndexSnapshot(const std::string& path);

}  // namespace placerec
