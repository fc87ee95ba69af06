#include "client/commands.h"

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "client/client.h"
#include "client/fleet.h"
#include "client/run_feeder.h"
#include "common/eval/alarms.h"
#include "common/eval/run.h"
#include "common/util/options.h"
#include "common/util/paths.h"
#include "proto/channels.h"

namespace placerec {
namespace {

// Set by the first SIGINT or SIGTERM of run and fleet: they stop sending, await the frames in
// flight and write their report; a second signal ends the process (the default action).
std::atomic<bool> g_interrupted{false};
static_assert(std::atomic<bool>::is_always_lock_free, "set from a signal handler");

void OnInterrupt(int) {
  g_interrupted = true;
  static const char kMessage[] =
      "\ninterrupted: no further frame is sent; waiting for the answers of the frames sent, then "
      "writing the report (interrupt again to quit without it)\n";
  (void)!write(STDERR_FILENO, kMessage, sizeof(kMessage) - 1);
}

void StopOnInterrupt() {
  struct sigaction action = {};
  action.sa_handler = OnInterrupt;
  action.sa_flags = SA_RESETHAND;  // the second signal takes the default action
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

int64_t NowUtime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// The LCM network alone: for commands that only listen (status, watch).
void AddLcmUrlFlag(FlagParser* parser, ClientOptions* options) {
  parser->Add("lcm-url", &options->lcm_url,
              "LCM URL (empty: LCM's default, i.e. $LCM_DEFAULT_URL or "
              "udpm://239.255.76.67:7667?ttl=0)");
}

// The network and how frames are sent: for commands that send frames.
void AddConnectionFlags(FlagParser* parser, ClientOptions* options) {
  AddLcmUrlFlag(parser, options);
  parser->Add("timeout", &options->timeout_s, "seconds to wait for each answer");
  parser->Add("key-file", &options->key_file,
              "keys file (a line 'ID PERMISSION KEY' from the server's operator, "
              "scripts/make-key.sh): frames are signed with its key and only answers signed with "
              "it are accepted; empty: unsigned frames, for a server run with --auth off");
  parser->Add("key-id", &options->key_id, "which key of --key-file to use (empty: its first)");
  parser->Add("retry-after", &options->retry_after_s,
              "send a frame again (same request id) when its answer has not come after this "
              "many seconds, and again after each further interval until the timeout; 0: never");
  parser->Add("untrusted-grace", &options->untrusted_grace_s,
              "seconds to wait on for a signed answer once an answer not signed with the key came "
              "(a wrong key: the server's refusal is unsigned), then give up with what it said; "
              "0: wait the whole --timeout");
}

StatusOr<std::unique_ptr<PlacerecClient>> ConnectOrReport(const ClientOptions& options,
                                                          const char* command) {
  StatusOr<std::unique_ptr<PlacerecClient>> client = PlacerecClient::Connect(options);
  if (!client.ok()) {
    std::fprintf(stderr, "placerec-client %s: %s\n", command, client.status().ToString().c_str());
  }
  return client;
}

// The exit code of a failed Connect: a keys file that does not read or lacks the key asked for
// is a bad argument (2); LCM that does not open is a failure (1).
int ConnectExitCode(const Status& status) {
  return status.code() == StatusCode::kInvalidArgument || status.code() == StatusCode::kNotFound
             ? kExitUsage
             : kExitFailed;
}

// Sends each image as one frame of `robot`, one after the other; prints each answer.
int SendImages(const std::vector<std::string>& images, const std::string& robot,
               int64_t first_sequence, bool insert, const ClientOptions& options,
               const char* command) {
  if (images.empty()) {
    std::fprintf(stderr, "placerec-client %s: give at least one image (see --help)\n", command);
    return kExitUsage;
  }
  // The server would refuse the id, and its refusal cannot be signed with the robot's key.
  if (std::string why; !IsValidWireRobotId(robot, &why)) {
    std::fprintf(stderr, "placerec-client %s: --robot '%s': %s\n", command, robot.c_str(),
                 why.c_str());
    return kExitUsage;
  }
  StatusOr<std::unique_ptr<PlacerecClient>> client = ConnectOrReport(options, command);
  if (!client.ok()) return ConnectExitCode(client.status());
  int failures = 0;
  int64_t sequence = first_sequence;
  for (const std::string& path : images) {
    StatusOr<EncodedImage> image = EncodeImageFile(path);
    if (!image.ok()) {
      std::fprintf(stderr, "placerec-client %s: %s\n", command, image.status().ToString().c_str());
      ++failures;
      continue;
    }
    OutgoingFrame frame;
    frame.robot = robot;
    frame.sequence = sequence++;
    frame.utime = NowUtime();
    frame.insert = insert;
    frame.image = std::move(*image);
    const FrameResult result = (*client)->Send(frame);
    std::printf("%s -> %s #%lld: %s (%.0f ms)\n", path.c_str(), robot.c_str(),
                static_cast<long long>(frame.sequence), DescribeResult(result).c_str(),
                result.latency_ms);
    if (!insert && result.ok()) {
      for (size_t i = 0; i < result.matches.size(); ++i) {
        const MatchedPlace& m = result.matches[i];
        std::printf("  %zu. robot %s #%lld  score %.0f  %d landmarks matched  place %lld%s\n",
                    i + 1, m.robot.c_str(), static_cast<long long>(m.sequence), m.score,
                    m.matched_landmarks, static_cast<long long>(m.place_id),
                    DescribeClasses(m.classes).c_str());
      }
    }
    std::fflush(stdout);
    if (!result.ok()) {
      ++failures;
      std::fprintf(stderr, "placerec-client %s: %s #%lld: %s: %s\n", command, robot.c_str(),
                   static_cast<long long>(frame.sequence), AnswerCodeName(result.code),
                   result.message.c_str());
    }
  }
  return failures == 0 ? kExitOk : kExitFailed;
}

// A dataset given by name (e.g. gardens_point) is looked up under PLACEREC_DATA or
// ../shared/data when it is not a directory itself.
StatusOr<Run> LoadNamedRun(const std::string& dataset, const std::string& run_name,
                           const std::string& data_default) {
  StatusOr<std::string> dir = FindDataset(dataset, DataDir("", data_default));
  if (!dir.ok()) return dir.status();
  return LoadRun(*dir, run_name);
}

// A dataset or run that is not there is a bad argument (2); one that cannot be read, a failure.
int RunLoadExitCode(const Status& status) {
  return status.code() == StatusCode::kNotFound ? kExitUsage : kExitFailed;
}

}  // namespace

const char kClientUsage[] =
    "placerec-client COMMAND [options]\n\n"
    "Talks to a placerec-server over LCM.\n\n"
    "Commands:\n"
    "  send IMAGE...   insert frames of one robot, one after the other, and print each answer\n"
    "  query IMAGE...  ask where each image was taken (query only: the map does not change)\n"
    "  status          print the server's next heartbeat\n"
    "  run             feed a run (../shared/data layout) and write OUT/answers.csv\n"
    "  fleet           N simulated robots replaying a run at a fixed rate: throughput, latency\n"
    "  watch           print scene-change alarms as they arrive and save their pictures\n\n"
    "'placerec-client COMMAND --help' lists the options of a command. Exit codes: 0 when every\n"
    "request got an answer with status ok, 1 when one timed out or carried an error, 2 for bad\n"
    "arguments, 130 when run or fleet was interrupted before every frame was sent (Ctrl-C: the\n"
    "frames sent are awaited and the report of them written; a second Ctrl-C quits at once).";

int SendCommand(int argc, const char* const* argv) {
  std::vector<std::string> images;
  std::string robot = "client";
  int64_t sequence = 0;
  ClientOptions options;
  FlagParser parser(
      "placerec-client send IMAGE... [--robot ID] [--sequence N] [options]\n\n"
      "Sends each image as a frame of robot ID (sequence N, N+1, ...; capture time now) to be\n"
      "inserted into the map, waits for each answer and prints it. JPEG and PNG files go as they\n"
      "are, other images as raw BGR.");
  parser.AddPositional("image", &images, "image files");
  parser.Add("robot", &robot, "robot id (1..47 bytes)");
  parser.Add("sequence", &sequence,
             "sequence number of the first image; must be after the robot's last one");
  AddConnectionFlags(&parser, &options);
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 2, "placerec-client send")) {
    return *exit;
  }
  return SendImages(images, robot, sequence, true, options, "send");
}

int QueryCommand(int argc, const char* const* argv) {
  std::vector<std::string> images;
  std::string robot = "query";
  int64_t sequence = 0;
  ClientOptions options;
  FlagParser parser(
      "placerec-client query IMAGE... [options]\n\n"
      "Asks where each image was taken: the server answers from its map with the best matching\n"
      "places, and neither the map nor any robot's state changes.");
  parser.AddPositional("image", &images, "image files");
  parser.Add("robot", &robot,
             "robot id the query is sent as (its own recent past is skipped: places younger "
             "than min-same-robot-gap-seconds or in a view it still sees)");
  parser.Add("sequence", &sequence, "sequence number sent with the first image");
  AddConnectionFlags(&parser, &options);
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 2, "placerec-client query")) {
    return *exit;
  }
  return SendImages(images, robot, sequence, false, options, "query");
}

int StatusCommand(int argc, const char* const* argv) {
  ClientOptions options;
  options.timeout_s = 3.0;
  FlagParser parser(
      "placerec-client status [options]\n\n"
      "Waits for the server's next heartbeat on PLACEREC_STATUS and prints it.");
  AddLcmUrlFlag(&parser, &options);
  parser.Add("timeout", &options.timeout_s, "seconds to wait for a heartbeat");
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 2, "placerec-client status")) {
    return *exit;
  }
  StatusOr<std::unique_ptr<PlacerecClient>> client = ConnectOrReport(options, "status");
  if (!client.ok()) return ConnectExitCode(client.status());
  StatusOr<ServerStatus> status = (*client)->WaitForStatus(options.timeout_s);
  if (!status.ok()) {
    std::fprintf(stderr, "placerec-client status: %s\n", status.status().message().c_str());
    return kExitFailed;
  }
  const ServerStatus& s = *status;
  std::printf(
      "placerec-server %s, up %.0f s\n"
      "  map: %s: %lld places, %lld landmarks, %lld descriptors (loaded in %.0f ms)\n"
      "  queue: %d of %d waiting, %d in progress on %d workers\n"
      "  frames: %lld answered (%lld errors, %lld overloaded), %.2f frames/s; %d robots; "
      "%lld invalid messages dropped\n",
      s.version.c_str(), s.uptime_s, s.map.c_str(), static_cast<long long>(s.map_places),
      static_cast<long long>(s.map_landmarks), static_cast<long long>(s.map_descriptors),
      s.map_open_ms, s.queue_depth, s.queue_capacity, s.in_progress, s.workers,
      static_cast<long long>(s.frames_answered), static_cast<long long>(s.frames_failed),
      static_cast<long long>(s.frames_overloaded), s.frames_per_second, s.robots,
      static_cast<long long>(s.messages_dropped));
  return kExitOk;
}

int WatchCommand(int argc, const char* const* argv) {
  ClientOptions options;
  std::string out;
  double duration_s = 0;
  int max_alarms = 0;
  FlagParser parser(
      "placerec-client watch [--out DIR] [options]\n\n"
      "Prints every scene-change alarm (PLACEREC_CHANGE, seed §7.2.4) as it arrives: the robot\n"
      "and frame, the known place and its earlier visit, what appeared or disappeared where, its\n"
      "class and confidence. With --out, saves the frame with the boxes drawn as\n"
      "DIR/<robot>_<sequence>_frame.jpg and the stored place as DIR/<robot>_<sequence>_place.jpg,\n"
      "and every alarm as a line of DIR/alarms.csv (written afresh; placerec-eval alarms scores\n"
      "it against a changed run). Runs until interrupted, --duration or --max-alarms.");
  parser.Add("out", &out,
             "folder for the alarm pictures and alarms.csv (created; empty: nothing saved)");
  parser.Add("duration", &duration_s, "stop after this many seconds (0: run until interrupted)");
  parser.Add("max-alarms", &max_alarms, "stop after this many alarms (0: no limit)");
  AddLcmUrlFlag(&parser, &options);  // alarms are not signed: no key is needed to watch
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 2, "placerec-client watch")) {
    return *exit;
  }
  if (duration_s < 0 || max_alarms < 0) {
    std::fprintf(stderr, "placerec-client watch: --duration and --max-alarms must be >= 0\n");
    return kExitUsage;
  }
  if (!out.empty() && !MakeDirectories(out)) {
    std::fprintf(stderr, "placerec-client watch: cannot create or write in %s\n", out.c_str());
    return kExitFailed;
  }
  std::ofstream alarms_csv;
  if (!out.empty()) {
    alarms_csv.open(out + "/alarms.csv", std::ios::trunc);
    alarms_csv << WatchedAlarmHeader() << '\n' << std::flush;
    if (!alarms_csv) {
      std::fprintf(stderr, "placerec-client watch: cannot write %s/alarms.csv\n", out.c_str());
      return kExitFailed;
    }
  }
  // What the alarm callback uses is declared before the client, so that it outlives the
  // client's receiving thread.
  std::mutex mutex;
  std::condition_variable done;
  int alarms = 0;
  bool write_failed = false;
  StatusOr<std::unique_ptr<PlacerecClient>> client = ConnectOrReport(options, "watch");
  if (!client.ok()) return ConnectExitCode(client.status());
  const auto save = [](const std::string& path, const std::vector<uint8_t>& bytes) {
    if (bytes.empty()) return true;
    std::ofstream file(path, std::ios::binary);
    file.write(reinterpret_cast<const char*>(bytes.data()),
               static_cast<std::streamsize>(bytes.size()));
    return static_cast<bool>(file.flush());
  };
  const Status watching = (*client)->WatchAlarms([&](const SceneAlarm& a) {
    std::lock_guard lock(mutex);
    std::printf(
        "%s #%lld at place %lld (%s #%lld, %.1f s earlier): %s %s at %d,%d %dx%d of %dx%d, "
        "confidence %.2f (%d of %d)\n",
        a.robot.c_str(), static_cast<long long>(a.sequence), static_cast<long long>(a.place_id),
        a.place_robot.c_str(), static_cast<long long>(a.place_sequence),
        static_cast<double>(a.frame_utime - a.place_utime) / 1e6,
        a.change.appeared ? "appeared" : "disappeared",
        a.change.object_class.empty() ? "object" : a.change.object_class.c_str(), a.change.x,
        a.change.y, a.change.width, a.change.height, a.frame_width, a.frame_height,
        a.change.confidence, a.change_index + 1, a.num_frame_changes);
    std::fflush(stdout);
    if (alarms_csv.is_open()) {
      WatchedAlarm line;
      line.robot = a.robot;
      line.sequence = a.sequence;
      line.frame_utime = a.frame_utime;
      line.place_id = a.place_id;
      line.place_robot = a.place_robot;
      line.place_utime = a.place_utime;
      line.appeared = a.change.appeared;
      line.box = cv::Rect(a.change.x, a.change.y, a.change.width, a.change.height);
      line.frame_size = cv::Size(a.frame_width, a.frame_height);
      line.object_class = a.change.object_class;
      line.confidence = a.change.confidence;
      alarms_csv << WatchedAlarmLine(line) << '\n' << std::flush;
      if (!alarms_csv) {
        std::fprintf(stderr, "placerec-client watch: cannot write %s/alarms.csv\n", out.c_str());
        write_failed = true;
      }
    }
    if (!out.empty() && a.change_index == 0) {
      const std::string stem = out + "/" + a.robot + "_" + std::to_string(a.sequence) + "_";
      if (!save(stem + "frame.jpg", a.frame_jpeg) || !save(stem + "place.jpg", a.place_jpeg)) {
        std::fprintf(stderr, "placerec-client watch: cannot write pictures to %s\n", out.c_str());
        write_failed = true;
      }
    }
    ++alarms;
    done.notify_all();
  });
  if (!watching.ok()) {
    std::fprintf(stderr, "placerec-client watch: %s\n", watching.ToString().c_str());
    return kExitFailed;
  }
  std::unique_lock lock(mutex);
  const auto stop = [&] { return (max_alarms > 0 && alarms >= max_alarms) || write_failed; };
  if (duration_s > 0) {
    done.wait_for(lock, std::chrono::duration<double>(duration_s), stop);
  } else {
    done.wait(lock, stop);
  }
  return write_failed ? kExitFailed : kExitOk;
}

int RunCommand(int argc, const char* const* argv, const std::string& data_default) {
  std::string dataset;
  std::string run_name;
  std::string out;
  bool quiet = false;
  bool no_loops = false;
  FeedOptions feed;
  ClientOptions options;
  FlagParser parser(
      "placerec-client run --dataset DIR --run NAME --out OUT [options]\n\n"
      "Feeds every frame of a run (layout of shared/data/README.md) to the server as its robot,\n"
      "sequence number = frame index, capture time from the run, prints each loop closure as it\n"
      "arrives, and writes OUT/answers.csv (frame,reference,score; -1 for none, exactly as\n"
      "placerec-eval run), OUT/summary.json (scores, latency, throughput) and OUT/pr_curve.png.");
  parser.AddRequired("dataset", &dataset,
                     "dataset directory, or its name under PLACEREC_DATA / ../shared/data");
  parser.AddRequired("run", &run_name, "run name (DIR/runs/NAME.frames.csv)");
  parser.AddRequired("out", &out, "output directory (created if missing)");
  parser.Add("window", &feed.window,
             "frames in flight at once (1: send the next frame after the answer, as placerec-eval "
             "feeds them)");
  parser.AddSwitch("concurrent-robots", &feed.robots_concurrently,
                   "one sender per robot, all at once (answers then depend on timing)");
  parser.Add("max-frames", &feed.max_frames, "stop after this many frames (0: all)");
  parser.AddSwitch("quiet", &quiet, "no progress line");
  parser.AddSwitch("no-loops", &no_loops, "do not print loop closures");
  AddConnectionFlags(&parser, &options);
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 2, "placerec-client run")) {
    return *exit;
  }
  feed.timeout_s = options.timeout_s;
  feed.progress = !quiet;
  feed.print_loop_closures = !no_loops;
  std::string error;
  if (!feed.Check(&error)) {
    std::fprintf(stderr, "placerec-client run: %s\n", error.c_str());
    return kExitUsage;
  }
  StatusOr<Run> run = LoadNamedRun(dataset, run_name, data_default);
  if (!run.ok()) {
    std::fprintf(stderr, "placerec-client run: %s\n", run.status().ToString().c_str());
    return RunLoadExitCode(run.status());
  }
  StatusOr<std::unique_ptr<PlacerecClient>> client = ConnectOrReport(options, "run");
  if (!client.ok()) return ConnectExitCode(client.status());
  feed.stop = &g_interrupted;
  StopOnInterrupt();
  StatusOr<FeedReport> report = FeedRun(client->get(), *run, feed);
  if (!report.ok()) {
    std::fprintf(stderr, "placerec-client run: %s\n", report.status().ToString().c_str());
    return kExitFailed;
  }
  const Status written = WriteFeedReport(out, *report);
  if (!written.ok()) {
    std::fprintf(stderr, "placerec-client run: %s\n", written.ToString().c_str());
    return kExitFailed;
  }
  const nlohmann::json& s = report->summary;
  std::printf(
      "%s/%s through placerec-server: %d frames, %d answered ok, %d errors, %d timed out, %d "
      "not sent\n"
      "  %d revisits, %d answered; recall at 100%% precision %.3f, max F1 %.3f, average "
      "precision %.3f\n"
      "  loop closures: %d (precision %.3f, recall %.3f)\n"
      "  latency (publish to answer) median %.0f ms, p90 %.0f ms; server time median %.0f ms\n"
      "  %.2f frames/s over %.1f s\n"
      "  wrote %s/answers.csv, summary.json, pr_curve.png\n",
      s["dataset"].get<std::string>().c_str(), s["run"].get<std::string>().c_str(),
      s["frames"].get<int>(), report->ok, report->failed, report->timed_out, report->not_sent,
      s["revisit_frames"].get<int>(), s["answered_frames"].get<int>(),
      s["recall_at_100_precision"].get<double>(), s["max_f1"].get<double>(),
      s["average_precision"].get<double>(), s["loop_closures"].get<int>(),
      s["decision"]["precision"].get<double>(), s["decision"]["recall"].get<double>(),
      s["latency"]["median_ms"].get<double>(), s["latency"]["p90_ms"].get<double>(),
      s["server_time"]["median_ms"].get<double>(), s["frames_per_second"].get<double>(),
      s["wall_seconds"].get<double>(), out.c_str());
  // Interrupted before every frame was sent (after that, a signal changes nothing: the answers
  // are awaited as always).
  if (s.value("interrupted", false)) return kExitInterrupted;
  if (!report->all_ok()) {
    for (const FrameResult& r : report->results) {
      if (!r.ok() && r.message != "not sent") {
        std::fprintf(stderr, "placerec-client run: first problem: %s #%lld: %s: %s\n",
                     r.robot.c_str(), static_cast<long long>(r.sequence), AnswerCodeName(r.code),
                     r.message.c_str());
        break;
      }
    }
    return kExitFailed;
  }
  return kExitOk;
}

int FleetCommand(int argc, const char* const* argv, const std::string& data_default) {
  std::string dataset;
  std::string run_name;
  std::string out;
  bool quiet = false;
  FleetOptions fleet;
  ClientOptions options;
  FlagParser parser(
      "placerec-client fleet --robots N --rate HZ --duration S --dataset DIR --run NAME --out "
      "OUT\n\n"
      "Simulates a fleet: N robots (ids fleet000, ...) replay the run's frames at HZ frames per\n"
      "second each, open loop, robot i starting i/N of the way along the route, for S seconds;\n"
      "then waits for the last answers. Prints and writes OUT/fleet.json: answers by status,\n"
      "answered frames per second, latency percentiles, overloaded answers, timeouts; and\n"
      "OUT/acknowledged.csv: robot, sequence number and place id of every place a server\n"
      "acknowledged storing.");
  parser.AddRequired("dataset", &dataset,
                     "dataset directory, or its name under PLACEREC_DATA / ../shared/data");
  parser.AddRequired("run", &run_name, "run name (DIR/runs/NAME.frames.csv)");
  parser.AddRequired("out", &out, "output directory (created if missing)");
  parser.Add("robots", &fleet.robots, "simulated robots");
  parser.Add("rate", &fleet.rate_hz, "frames per second per robot");
  parser.Add("duration", &fleet.duration_s, "seconds of sending");
  parser.Add("query-share", &fleet.query_share,
             "share of each robot's frames sent query-only (the rest are inserted)");
  parser.Add("robot-prefix", &fleet.robot_prefix, "robot ids are PREFIX000, PREFIX001, ...");
  parser.AddSwitch("quiet", &quiet, "no progress line");
  AddConnectionFlags(&parser, &options);
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 2, "placerec-client fleet")) {
    return *exit;
  }
  fleet.timeout_s = options.timeout_s;
  fleet.progress = !quiet;
  std::string error;
  if (!fleet.Check(&error)) {
    std::fprintf(stderr, "placerec-client fleet: %s\n", error.c_str());
    return kExitUsage;
  }
  StatusOr<Run> run = LoadNamedRun(dataset, run_name, data_default);
  if (!run.ok()) {
    std::fprintf(stderr, "placerec-client fleet: %s\n", run.status().ToString().c_str());
    return RunLoadExitCode(run.status());
  }
  StatusOr<std::unique_ptr<PlacerecClient>> client = ConnectOrReport(options, "fleet");
  if (!client.ok()) return ConnectExitCode(client.status());
  fleet.stop = &g_interrupted;
  StopOnInterrupt();
  StatusOr<FleetReport> report = RunFleet(client->get(), *run, fleet);
  if (!report.ok()) {
    std::fprintf(stderr, "placerec-client fleet: %s\n", report.status().ToString().c_str());
    return kExitFailed;
  }
  if (!MakeDirectories(out)) {
    std::fprintf(stderr, "placerec-client fleet: cannot create or write in %s\n", out.c_str());
    return kExitFailed;
  }
  if (!(std::ofstream(out + "/fleet.json") << report->summary.dump(2) << "\n")) {
    std::fprintf(stderr, "placerec-client fleet: cannot write %s/fleet.json\n", out.c_str());
    return kExitFailed;
  }
  // Every place a server acknowledged storing: each must be in the map, whatever happens to a
  // server afterwards.
  std::ofstream acknowledged(out + "/acknowledged.csv");
  acknowledged << "robot,sequence,place_id\n";
  for (const FrameResult& r : report->results) {
    if (r.ok() && r.insert && r.place_id >= 0) {
      acknowledged << r.robot << ',' << r.sequence << ',' << r.place_id << '\n';
    }
  }
  if (!acknowledged.flush()) {
    std::fprintf(stderr, "placerec-client fleet: cannot write %s/acknowledged.csv\n", out.c_str());
    return kExitFailed;
  }
  const nlohmann::json& s = report->summary;
  std::printf(
      "fleet of %d robots at %.2f Hz (%.1f frames/s offered) for %.0f s: %d frames sent, %d not "
      "sent, %d ok, %d overloaded, %d timed out; %.2f answered ok per second; latency p50 %.0f "
      "ms, p90 %.0f ms, p99 %.0f ms\n",
      fleet.robots, fleet.rate_hz, s["offered_frames_per_second"].get<double>(), fleet.duration_s,
      report->frames, s["not_sent"].get<int>(), s["ok"].get<int>(), s["overloaded"].get<int>(),
      s["timed_out"].get<int>(), s["answered_ok_per_second"].get<double>(),
      s["latency_ms"]["p50"].get<double>(), s["latency_ms"]["p90"].get<double>(),
      s["latency_ms"]["p99"].get<double>());
  if (s.value("interrupted", false)) return kExitInterrupted;
  // Every frame offered must have been sent and answered ok.
  return s["ok"].get<int>() == report->frames && s["not_sent"].get<int>() == 0 ? kExitOk
                                                                               : kExitFailed;
}

}  // namespace placerec
