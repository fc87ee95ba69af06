// placerec-map: the map tools (issue 22 item 5), on a map file without a running server.
//   placerec-map info --db FILE [--json]
//   placerec-map export --db FILE --out DIR
//   placerec-map prune --db FILE (--before UTIME_OR_ISO_DATE | --robot ID) [--dry-run]
//   placerec-map merge A B --out C [--suffix .b]
//   placerec-map check --db FILE
//   placerec-map index --db FILE
// The work is in map_tools.h; this file parses flags and prints the reports.
#include <cstdio>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "common/util/logging.h"
#include "common/util/options.h"
#include "tools/map_tools.h"

namespace placerec {
namespace {

constexpr char kUsage[] =
    "placerec-map COMMAND [options]\n\n"
    "Works on a placerec map file (the SQLite file of placerec-server --db) without a server.\n"
    "info, export and check only read, and may run while a server has the map open; prune\n"
    "refuses a map another process holds open, and merge writes a new file.\n\n"
    "Commands:\n"
    "  info     places, landmarks and descriptors by robot and by object class, size, version\n"
    "  export   DIR/places.csv, DIR/route.png (the map per robot), the place thumbnails\n"
    "  prune    drop places before a time or of a robot, with their landmarks and sightings\n"
    "  merge    two maps into a new one, robot ids kept apart\n"
    "  check    the full integrity check (exit code 0: whole, 1: damaged)\n"
    "  index    write the descriptor index snapshot FILE.index, for a fast server start\n\n"
    "'placerec-map COMMAND --help' lists the options of a command.";

int Fail(const char* command, const Status& status) {
  std::fprintf(stderr, "%s: %s\n", command, status.ToString().c_str());
  return 1;
}

int InfoCommand(int argc, char** argv) {
  std::string db;
  bool json = false;
  FlagParser parser(
      "placerec-map info --db FILE [--json]\n\n"
      "Prints the map's places, landmarks, descriptors and sightings, by robot (with its\n"
      "sequence numbers and time span) and by object class, its file size and schema version.\n"
      "Reads only: the map may be open in a running server.");
  parser.AddRequired("db", &db, "map file");
  parser.AddSwitch("json", &json, "print one JSON object instead of text");
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 2, "placerec-map info")) {
    return *exit;
  }
  StatusOr<MapInfo> info = ReadMapInfo(db);
  if (!info.ok()) return Fail("placerec-map info", info.status());
  if (json) {
    // Robot ids and classes of older maps may hold bytes that are no UTF-8: replaced, not fatal.
    std::printf(
        "%s\n",
        info->ToJson().dump(2, ' ', false, nlohmann::json::error_handler_t::replace).c_str());
  } else {
    std::printf("%s", info->ToText().c_str());
  }
  return 0;
}

int ExportCommand(int argc, char** argv) {
  std::string db;
  std::string out;
  FlagParser parser(
      "placerec-map export --db FILE --out DIR\n\n"
      "Writes DIR/places.csv (id,robot,sequence,utime,landmarks,descriptors,classes,thumbnail;\n"
      "classes as building:3;sign:1, unclassified landmarks last), DIR/route.png: per robot a\n"
      "timeline strip of its places coloured by landmark count, the class shares of their\n"
      "landmarks and the robot's class counts, and, for maps with place pictures (schema 3),\n"
      "DIR/thumbnails/<place id>.jpg and DIR/contact_sheet.jpg, the route's pictures in order.\n"
      "Reads the map only. Into the folder of an earlier export it removes, once done, the\n"
      "thumbnails that export's places.csv listed and this one does not write again (and its\n"
      "contact sheet when this one has none); other files are left alone.");
  parser.AddRequired("db", &db, "map file");
  parser.AddRequired("out", &out, "output directory (created if missing)");
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 2, "placerec-map export")) {
    return *exit;
  }
  StatusOr<ExportReport> report = ExportMap(db, out);
  if (!report.ok()) return Fail("placerec-map export", report.status());
  std::printf("%lld places of %lld robot%s: wrote %s and %s",
              static_cast<long long>(report->places), static_cast<long long>(report->robots),
              report->robots == 1 ? "" : "s", report->csv_path.c_str(),
              report->picture_path.c_str());
  if (report->thumbnails > 0) {
    std::printf(", %lld thumbnails and %s", static_cast<long long>(report->thumbnails),
                report->contact_sheet_path.c_str());
  }
  std::printf("\n");
  return 0;
}

int PruneCommand(int argc, char** argv) {
  std::string db;
  std::string before;
  PruneOptions options;
  FlagParser parser(
      "placerec-map prune --db FILE (--before UTIME_OR_ISO_DATE | --robot ID) [--dry-run]\n\n"
      "Drops the places captured before a time, or of a robot (both: that robot's places before\n"
      "the time), with their landmarks, the sightings of those landmarks and the sightings by\n"
      "those places, in one transaction: the server's next start sees a consistent map, and on\n"
      "any error nothing changes. Refuses a map another process (a running server) holds open\n"
      "(--dry-run only counts, and may run beside it).\n"
      "The file keeps its size; SQLite reuses the freed pages.");
  parser.AddRequired("db", &db, "map file");
  parser.Add("before", &before,
             "drop places captured before this time: microseconds since the epoch, or an ISO "
             "date or UTC time (2026-12-01, 2026-12-01T08:30:15Z)");
  parser.Add("robot", &options.robot, "drop the places of this robot id");
  parser.AddSwitch("dry-run", &options.dry_run, "report what would be dropped, change nothing");
  parser.Add("busy-timeout-ms", &options.busy_timeout_ms,
             "wait this long for another process's lock before refusing the map (milliseconds)");
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 2, "placerec-map prune")) {
    return *exit;
  }
  if (!before.empty()) {
    StatusOr<int64_t> utime = ParseTimeArgument(before);
    if (!utime.ok()) {
      std::fprintf(stderr, "placerec-map prune: %s\n", utime.status().message().c_str());
      return 2;
    }
    options.before_utime = *utime;
  }
  std::string error;
  if (!options.Check(&error)) {
    std::fprintf(stderr, "placerec-map prune: %s (see --help)\n", error.c_str());
    return 2;
  }
  StatusOr<PruneReport> report = PruneMap(db, options);
  if (!report.ok()) return Fail("placerec-map prune", report.status());
  if (report->robot_unknown) {
    std::string robots;
    for (const std::string& robot : report->robots) robots += (robots.empty() ? "" : ", ") + robot;
    std::fprintf(stderr, "placerec-map prune: warning: %s has no robot '%s' (%s)\n", db.c_str(),
                 options.robot.c_str(),
                 robots.empty() ? "it has no places" : ("its robots: " + robots).c_str());
  }
  std::printf("%s %lld places, %lld landmarks (%lld descriptors), %lld sightings\n",
              report->dry_run ? "would drop" : "dropped", static_cast<long long>(report->places),
              static_cast<long long>(report->landmarks),
              static_cast<long long>(report->descriptors),
              static_cast<long long>(report->sightings));
  for (const auto& [robot, places] : report->places_by_robot) {
    std::printf("  %s: %lld places\n", robot.c_str(), static_cast<long long>(places));
  }
  std::printf("%s %lld places, %lld landmarks\n", report->dry_run ? "would keep" : "kept",
              static_cast<long long>(report->places_kept),
              static_cast<long long>(report->landmarks_kept));
  return 0;
}

int MergeCommand(int argc, char** argv) {
  std::vector<std::string> maps;
  std::string out;
  MergeOptions options;
  FlagParser parser(
      "placerec-map merge A B --out C [--suffix .b]\n\n"
      "Writes a new map C holding every place of A, then every place of B, with their landmarks\n"
      "(new ids; sightings follow their landmarks). Robot ids stay apart: a robot id of B that\n"
      "A also has becomes ID + suffix (ID.b; ID.b2, ID.b3, ... when that is taken in A or B).\n"
      "A new id over the 47-byte robot id limit is refused before anything is written. C must\n"
      "not exist; it is written to C.merging.<host>.<pid> and moved to C when complete, never\n"
      "replacing a file, also on file systems without hard links such as exFAT (there a merge\n"
      "killed within the move may leave an empty C: remove it). What a killed merge on this\n"
      "machine left, its process no longer running, is removed. A and B are\n"
      "only read (a map of an older schema version is read as it is, not upgraded); C is written\n"
      "in the current schema version.");
  parser.AddPositional("maps", &maps, "the two maps A and B");
  parser.AddRequired("out", &out, "the merged map to write (must not exist)");
  parser.Add("suffix", &options.suffix,
             "appended to B's robot ids that A has too (letters, digits, '_', '-', '.')");
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 2, "placerec-map merge")) {
    return *exit;
  }
  if (maps.size() != 2) {
    std::fprintf(stderr, "placerec-map merge: give exactly two maps, A and B (see --help)\n");
    return 2;
  }
  std::string error;
  if (!options.Check(&error)) {
    std::fprintf(stderr, "placerec-map merge: %s\n", error.c_str());
    return 2;
  }
  StatusOr<MergeReport> report = MergeMaps(maps[0], maps[1], out, options);
  if (!report.ok()) return Fail("placerec-map merge", report.status());
  for (const std::string& file : report->removed_work_files) {
    std::printf("removed %s, left by a merge that did not finish\n", file.c_str());
  }
  for (const MergeInput* input : {&report->a, &report->b}) {
    std::printf(
        "%s: %lld places, %lld landmarks (%lld descriptors), %lld sightings\n", input->path.c_str(),
        static_cast<long long>(input->places), static_cast<long long>(input->landmarks),
        static_cast<long long>(input->descriptors), static_cast<long long>(input->sightings));
    if (input->times_moved > 0) {
      std::printf(
          "  note: %lld places of %s had a capture time outside 0 .. year 9999; written with the "
          "time the server uses for them (the nearest end of the range)\n",
          static_cast<long long>(input->times_moved), input->path.c_str());
    }
  }
  for (const auto& [from, to] : report->renamed) {
    std::printf("  robot %s of %s is %s in the merged map\n", from.c_str(), maps[1].c_str(),
                to.c_str());
  }
  std::printf("wrote %s: %lld places, %lld landmarks\n", out.c_str(),
              static_cast<long long>(report->places), static_cast<long long>(report->landmarks));
  return 0;
}

int CheckCommand(int argc, char** argv) {
  std::string db;
  FlagParser parser(
      "placerec-map check --db FILE\n\n"
      "The full integrity check: SQLite's integrity_check, the foreign keys (every landmark's\n"
      "place, every sighting's place and landmark), each place's landmark count, then every\n"
      "place and landmark read back and validated (reading stops at the first damaged\n"
      "landmark). Exit code 0 when the map is whole, 1 when it is damaged or cannot be read.\n"
      "Only reads: a map of an older schema version is read as it is (not upgraded), and a\n"
      "write-ahead log (MAP-wal) a killed server left is read, not folded into the file.");
  parser.AddRequired("db", &db, "map file");
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 2, "placerec-map check")) {
    return *exit;
  }
  StatusOr<CheckReport> report = CheckMap(db);
  if (!report.ok()) return Fail("placerec-map check", report.status());
  for (const std::string& note : report->notes) std::printf("note: %s\n", note.c_str());
  if (report->ok()) {
    std::printf("%s is whole: %lld places and %lld landmarks read back\n", db.c_str(),
                static_cast<long long>(report->places), static_cast<long long>(report->landmarks));
    return 0;
  }
  std::printf("%s is damaged (%lld places and %lld landmarks read back):\n", db.c_str(),
              static_cast<long long>(report->places), static_cast<long long>(report->landmarks));
  for (const std::string& problem : report->problems) std::printf("  %s\n", problem.c_str());
  std::printf(
      "restore the map from a backup, or repair it: placerec-server --repair drops the damaged "
      "places and keeps the damaged file beside the map\n");
  return 1;
}

int IndexCommand(int argc, char** argv) {
  std::string db;
  FlagParser parser(
      "placerec-map index --db FILE\n\n"
      "Opens the map as placerec-server does and writes the snapshot of its descriptor index\n"
      "(the FLANN tree over every stored descriptor) to FILE.index, so that the next server\n"
      "start loads the tree instead of growing it point by point (at a million landmark\n"
      "objects, most of the time a start takes). The server writes it itself on a clean\n"
      "shutdown; a snapshot that does not match the map (places added since, a pruned or\n"
      "merged map, damage) is ignored or extended on open, never trusted. It may run while a\n"
      "server has the map open (the snapshot then covers the places it read); a place committed\n"
      "while it reads can make it fail: run it again.\n"
      "Needs the memory of the server holding the map.");
  parser.AddRequired("db", &db, "map file");
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 2, "placerec-map index")) {
    return *exit;
  }
  StatusOr<IndexSnapshotReport> report = WriteIndexSnapshot(db);
  if (!report.ok()) return Fail("placerec-map index", report.status());
  if (report->written) {
    std::printf("wrote %s: %lld descriptors (map opened in %.1f s%s, snapshot written in %.1f s)\n",
                report->snapshot.c_str(), static_cast<long long>(report->descriptors),
                report->open_ms / 1000.0,
                report->started_from_snapshot ? " from an older snapshot" : "",
                report->write_ms / 1000.0);
  } else if (report->descriptors == 0) {
    std::printf("the map holds no descriptors: nothing to index%s\n",
                report->removed_stale ? ("; removed the stale " + report->snapshot).c_str() : "");
  } else {
    std::printf("%s already covers the map's %lld descriptors: nothing written\n",
                report->snapshot.c_str(), static_cast<long long>(report->descriptors));
  }
  return 0;
}

}  // namespace
}  // namespace placerec

int main(int argc, char** argv) {
  placerec::InitLogging(argv[0]);
  if (argc < 2 || std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0) {
    std::printf("%s\n", placerec::kUsage);
    return argc < 2 ? 2 : 0;
  }
  if (std::strcmp(argv[1], "info") == 0) return placerec::InfoCommand(argc, argv);
  if (std::strcmp(argv[1], "export") == 0) return placerec::ExportCommand(argc, argv);
  if (std::strcmp(argv[1], "prune") == 0) return placerec::PruneCommand(argc, argv);
  if (std::strcmp(argv[1], "merge") == 0) return placerec::MergeCommand(argc, argv);
  if (std::strcmp(argv[1], "check") == 0) return placerec::CheckCommand(argc, argv);
  if (std::strcmp(argv[1], "index") == 0) return placerec::IndexCommand(argc, argv);
  std::fprintf(stderr, "placerec-map: unknown command '%s'\n%s\n", argv[1], placerec::kUsage);
  return 2;
}
