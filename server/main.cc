// placerec-server: parses flags into ServerOptions, opens the map and LCM, and serves until
// SIGINT or SIGTERM. Exit codes: 0 after a clean stop, 1 when the map or LCM cannot be opened,
// 2 for bad flags.
#include <csignal>
#include <cstdio>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "common/pipeline/flags.h"
#include "common/util/logging.h"
#include "common/util/options.h"
#include "server/authenticator.h"
#include "server/server.h"

namespace placerec {
namespace {

Server* g_server = nullptr;

void OnStopSignal(int) {
  if (g_server != nullptr) g_server->Stop();
}

void OnReloadSignal(int) {
  if (g_server != nullptr) g_server->ReloadKeys();
}

constexpr char kUsage[] =
    "placerec-server [--db FILE|postgresql://...] [--robots ID,ID...] [--lcm-url URL]... "
    "[options]\n\n"
    "Serves place recognition over LCM: frames (placerec.frame_t) on PLACEREC_FRAME, one answer\n"
    "(placerec.result_t) per frame on PLACEREC_RESULT_<robot>, a heartbeat (placerec.status_t) on\n"
    "PLACEREC_STATUS every second. The landmark map lives in the SQLite file --db, or in a\n"
    "PostgreSQL database several servers share (--db postgresql://...; each server follows the\n"
    "others' inserts, and --robots splits the robots between them); it is reloaded at start-up,\n"
    "and each frame's landmarks are committed before its answer is published.\n"
    "Frames must be signed with a key of the --keys file (proto/README.md \"Signed frames\");\n"
    "SIGHUP reloads it. Stops cleanly on SIGINT or SIGTERM.";

int Main(int argc, char** argv) {
  ServerOptions options;
  bool sqlite_normal = false;
  std::string auth = "on";
  FlagParser parser(kUsage);
  std::string robots;
  int opencv_threads = 1;
  parser.Add("db", &options.db_path,
             "the map: a SQLite file (created when missing), or a PostgreSQL URL such as "
             "postgresql://user@host/placerec or postgresql:///placerec?host=/run/pg (a unix "
             "socket folder) for one map shared by several servers (scripts/pg.sh starts a "
             "throw-away cluster)");
  parser.Add("robots", &robots,
             "comma-separated robot (and device) ids this server answers; frames of other ids are "
             "left to other servers on the same network and map (default: every id)");
  parser.Add("pg-connect-timeout", &options.postgres.connect_timeout_s,
             "seconds a connection to a PostgreSQL map may take before it counts as lost");
  parser.Add("pg-insert-timeout-ms", &options.postgres.insert_timeout_ms,
             "milliseconds an insert into a PostgreSQL map may wait for the map's insert lock (and "
             "each of its statements may run) before its frame is answered STATUS_STORAGE_ERROR: "
             "another server stopped or cut off inside its insert keeps the lock until PostgreSQL "
             "ends its session");
  parser.AddRepeated(
      "lcm-url", &options.lcm_urls,
      "LCM URL of a network to serve; give it once per network, e.g. --lcm-url "
      "'udpm://239.255.76.67:7667?ttl=1' for the robot LAN and --lcm-url tcpq://127.0.0.1:7700 "
      "for remote devices through an LCM TCP hub (scripts/lcm-hub.sh); each answer goes back on "
      "the network its frame came from, heartbeats go to all (none: LCM's default, i.e. "
      "$LCM_DEFAULT_URL or udpm://239.255.76.67:7667?ttl=0)");
  parser.Add("keys", &options.auth.keys_file,
             "keys file: one line per robot or device, 'ID insert|query|both KEY' (64 hex digits; "
             "scripts/make-key.sh makes one); chmod 600; SIGHUP reloads it");
  parser.Add("auth", &auth,
             "on: only frames signed with a key of --keys are served, answers are signed; off: "
             "anyone on the network may insert and query (a lab LAN only)");
  parser.Add("auth-window", &options.auth.window_s,
             "seconds a frame's signing time may differ from the server's clock; also how long "
             "each key's counters are remembered against replays");
  parser.Add("workers", &options.workers,
             "worker threads running the pipeline (one robot's frames never run at once); 0: one "
             "per core this process may use (CPU affinity, a container's CPU quota)");
  parser.Add("opencv-threads", &opencv_threads,
             "threads OpenCV's own parallel loops (SIFT) may use in this process; 1: each frame "
             "runs on its worker's thread alone and --workers runs frames side by side; 0: "
             "OpenCV's default (all cores; docs/results.md, Speed, compares the two)");
  parser.Add("queue", &options.queue_capacity,
             "frames waiting for a worker before new ones are answered 'overloaded'");
  parser.Add("status-period", &options.status_period_s,
             "seconds between heartbeats on PLACEREC_STATUS");
  parser.AddSwitch("repair", &options.repair,
                   "before serving, drop the places of a damaged map that do not read back whole "
                   "(the damaged file is kept as <db>.damaged) and report how many");
  parser.AddSwitch("sqlite-sync-normal", &sqlite_normal,
                   "SQLite synchronous=NORMAL: commits survive a killed server but not a power "
                   "loss (default FULL: both)");
  parser.Add("sqlite-busy-timeout-ms", &options.store.busy_timeout_ms,
             "how long a write waits for another connection's lock, milliseconds");
  parser.Add("max-image-dimension", &options.decode.max_dimension,
             "frames larger than this in either dimension are rejected (pixels)");
  parser.Add("min-image-dimension", &options.decode.min_dimension,
             "frames smaller than this in either dimension are rejected (pixels)");
  parser.Add("max-image-pixels", &options.decode.max_pixels,
             "frames of more pixels (width x height) are rejected; JPEG and PNG sizes are read "
             "from the header before decoding");
  parser.Add("robot-restart-gap", &options.sequence_rule.restart_gap_s,
             "seconds after a robot's last accepted insert from which a lower sequence begins a "
             "new run of the robot (a restart) instead of being refused as out of order");
  parser.Add("max-robot-runs", &options.sequence_rule.max_robot_runs,
             "robots whose short-term memory (recent past, tracked landmarks) "
             "the server keeps; beyond it the robot silent longest is forgotten and its next "
             "frame begins a new run");
  AddRecognizerFlags(&parser, &options.recognizer);
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 1, "placerec-server")) {
    return *exit;
  }
  options.store.synchronous_full = !sqlite_normal;
  for (size_t begin = 0; begin < robots.size();) {
    size_t end = robots.find(',', begin);
    if (end == std::string::npos) end = robots.size();
    options.robots.push_back(robots.substr(begin, end - begin));
    begin = end + 1;
    if (end + 1 == robots.size()) options.robots.push_back("");  // a trailing comma: refused
  }
  if (auth != "on" && auth != "off") {
    std::fprintf(stderr, "placerec-server: --auth must be on or off\n");
    return 2;
  }
  options.auth.enabled = auth == "on";
  if (!options.auth.enabled) {
    std::fprintf(stderr,
                 "placerec-server: WARNING: AUTHENTICATION IS OFF (--auth off). Anyone who can "
                 "publish on the LCM network may insert frames under any robot's name and read "
                 "the map. Use this on a lab LAN only.\n");
  }
  std::string error;
  if (!options.Check(&error)) {
    std::fprintf(stderr, "placerec-server: %s\n", error.c_str());
    return 2;
  }
  if (opencv_threads < 0 || opencv_threads > 256) {
    std::fprintf(stderr, "placerec-server: --opencv-threads must be between 0 and 256\n");
    return 2;
  }
  // A process-wide setting of OpenCV: 0 asks for its default.
  cv::setNumThreads(opencv_threads == 0 ? -1 : opencv_threads);
  if (options.auth.enabled && options.auth.keys_file.empty()) {
    std::fprintf(stderr, "placerec-server: %s\n", MissingKeysAdvice().c_str());
    return 2;
  }
  StatusOr<std::unique_ptr<Server>> server = Server::Create(options);
  if (!server.ok()) {
    std::fprintf(stderr, "placerec-server: %s\n", server.status().ToString().c_str());
    return 1;
  }
  g_server = server->get();
  struct sigaction action = {};
  action.sa_handler = OnStopSignal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
  struct sigaction reload = {};
  reload.sa_handler = OnReloadSignal;
  sigemptyset(&reload.sa_mask);
  sigaction(SIGHUP, &reload, nullptr);
  const Status served = (*server)->Run();
  g_server = nullptr;
  if (!served.ok()) {
    std::fprintf(stderr, "placerec-server: %s\n", served.ToString().c_str());
    return 1;
  }
  return 0;
}

}  // namespace
}  // namespace placerec

int main(int argc, char** argv) {
  placerec::InitLogging(argv[0]);
  return placerec::Main(argc, argv);
}
