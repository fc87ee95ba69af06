// The soak (issue 23): placerec-server under a steady load for PLACEREC_SOAK_SECONDS (180 by
// default, as CI runs it; scripts/soak.sh runs 1800):
//
// - 8 robots, each sending its next frame as soon as the last one is answered, so the load is
//   paced by the server's own capacity; two inserts to one query-only frame.
// - One disk-full episode at 20 % of the time: the map's file system (a tmpfs of its own in a
//   private mount namespace) is filled for 5 % of the time (at least 10 s), and longer until an
//   insert has been refused (SQLite's write-ahead log may still hold a few inserts in pages it
//   reuses; the episode ends before the kill at the latest), then freed.
// - One SIGKILL and restart on the same map at 40 % of the time; the robots' clients send
//   unanswered frames again (ClientOptions::retry_after_s) until the new server answers.
// - The last 30 % of the time query-only frames on a map that no longer changes.
// - The server's resident memory sampled every second, and read with no frame in work early in
//   the query-only phase and at its end (the robots hold their frames until all are answered and
//   the server logs that it gave its free heap pages back, after 5 s without work).
//
// Checked: every frame is answered exactly once (one answer published per request id, none lost
// across the restart); the only failures are inserts answered "storage error" during the
// disk-full episode; inserts are stored again after it; every acknowledged insert's place is in
// the map at the end with its landmarks; and the idle server's memory does not grow during the
// query-only phase.
// Writes memory.csv and soak.json to PLACEREC_SOAK_OUT when it is set.
#include <fcntl.h>
#include <sched.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>
#include <nlohmann/json.hpp>

#include "client/client.h"
#include "common/eval/run.h"
#include "common/eval/stats.h"
#include "common/recognition/types.h"
#include "common/storage/sqlite_store.h"
#include "common/util/memory.h"
#include "common/util/paths.h"
#include "placerec/result_t.hpp"
#include "tests/service_harness.h"

namespace placerec {
namespace {

using Clock = std::chrono::steady_clock;
using testing_service::ChildProcess;
using testing_service::MakeTempDir;
using testing_service::RemoveTempDir;
using testing_service::StartServer;
using testing_service::StopServer;
using testing_service::Tail;
using testing_service::TestLcmUrl;

constexpr int kRobots = 8;
constexpr double kDiskFullAt = 0.2;        // share of the soak's time
constexpr double kDiskFullFor = 0.05;      // share of the soak's time (at least 10 s)
constexpr double kKillAt = 0.4;            // share of the soak's time
constexpr double kQueryOnlyFrom = 0.7;     // share of the soak's time
constexpr double kTailSettleShare = 0.25;  // of the query-only phase, before memory is compared
// What the server logs when it gives its free heap memory back (Server::TrimWhenIdle).
constexpr char kTrimmedLine[] = "free heap memory returned to the system";
constexpr int kTrimWaitSeconds = 60;  // for that line once the robots hold their frames

double SoakSeconds() {
  const char* env = std::getenv("PLACEREC_SOAK_SECONDS");
  const double s = env != nullptr ? std::atof(env) : 180.0;
  return s >= 60 ? s : 60.0;
}

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// Lines of the file at `path` that contain `text`.
int CountLinesWith(const std::string& path, const std::string& text) {
  std::ifstream in(path);
  int count = 0;
  for (std::string line; std::getline(in, line);) count += line.find(text) != std::string::npos;
  return count;
}

// Resident memory of `pid` in KiB, 0 when it cannot be read.
int64_t ResidentKib(pid_t pid) {
  ResidentMemory memory;
  return ReadResidentMemory(pid, &memory) ? static_cast<int64_t>(memory.current_mib * 1024) : 0;
}

// One answer as published: what tells a processed frame's answer from a copy of it.
struct Publication {
  int8_t status = 0;
  int64_t place_id = -1;
  double server_ms = 0;
  bool operator==(const Publication& o) const {
    return status == o.status && place_id == o.place_id && server_ms == o.server_ms;
  }
};

// Records the answers published on every answer channel, per robot and request id: "answered
// exactly once" is about what the server published, not only what the waiting client kept. A
// frame sent again while its answer crossed the copy on the wire is answered again from the
// server's record: the same answer, byte for byte, not a second processing.
class AnswerCounter {
 public:
  AnswerCounter() : lcm_(TestLcmUrl()) {
    lcm::Subscription* all = lcm_.subscribe("PLACEREC_RESULT.*", &AnswerCounter::OnAnswer, this);
    if (all != nullptr) all->setQueueCapacity(0);  // keep everything
    thread_ = std::thread([this] {
      while (!stop_) lcm_.handleTimeout(50);
    });
  }
  ~AnswerCounter() {
    stop_ = true;
    thread_.join();
  }
  bool good() { return lcm_.good(); }
  std::map<std::pair<std::string, int64_t>, std::vector<Publication>> published() {
    std::lock_guard lock(mutex_);
    return published_;
  }

 private:
  void OnAnswer(const lcm::ReceiveBuffer*, const std::string&, const result_t* answer) {
    std::lock_guard lock(mutex_);
    published_[{answer->robot, answer->request_id}].push_back(
        {answer->status, answer->place_id, answer->server_ms});
  }

  lcm::LCM lcm_;
  std::mutex mutex_;
  std::map<std::pair<std::string, int64_t>, std::vector<Publication>> published_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

// One frame a robot sent and what came back.
struct SentFrame {
  std::string robot;
  int64_t sequence = 0;
  int64_t request_id = 0;
  bool insert = false;
  double sent_s = 0;  // since the soak began
  int sends = 0;      // publications by the client (1 + retries)
  FrameResult result;
};

enum class Phase { kMixed, kDiskFull, kRestart, kQueryOnly };
const char* PhaseName(Phase phase) {
  switch (phase) {
    case Phase::kMixed:
      return "mixed";
    case Phase::kDiskFull:
      return "disk_full";
    case Phase::kRestart:
      return "restart";
    case Phase::kQueryOnly:
      return "query_only";
  }
  return "?";
}

struct MemorySample {
  double t_s = 0;
  Phase phase = Phase::kMixed;
  int64_t rss_kib = 0;
};

class SoakTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const Status network = testing_service::EnterPrivateNetwork();
    if (!network.ok()) GTEST_SKIP() << "the soak skipped: " << network.message();
    // A private mount namespace, so that the map's own small file system can be filled without
    // touching the machine's. Done before any thread starts; the server inherits it.
    if (unshare(CLONE_NEWNS) != 0 || mount(nullptr, "/", nullptr, MS_REC | MS_PRIVATE, nullptr)) {
      GTEST_SKIP() << "the soak skipped: no private mount namespace: " << std::strerror(errno);
    }
    dir_ = MakeTempDir("placerec_soak_");
    ASSERT_FALSE(dir_.empty());
    map_dir_ = dir_ + "/map";
    ASSERT_EQ(mkdir(map_dir_.c_str(), 0755), 0);
    // Large enough for a 30-minute soak's map; the disk-full episode fills what is left.
    ASSERT_EQ(mount("soak", map_dir_.c_str(), "tmpfs", 0, "size=3g"), 0) << std::strerror(errno);
    db_ = map_dir_ + "/map.db";
  }

  void TearDown() override {
    server_.reset();
    if (!map_dir_.empty()) umount2(map_dir_.c_str(), MNT_DETACH);
    RemoveTempDir(dir_);
  }

  // The frames robots send: a real indoor loop and a real outdoor route, one encoded image each.
  bool LoadImages(std::vector<EncodedImage>* images, std::string* why) {
    const std::string root = DataDir("", PLACEREC_DEFAULT_DATA_DIR);
    for (const auto& [dataset, run_name] :
         {std::pair<std::string, std::string>{"rtabmap_indoor", "corridor_loop"},
          {"gardens_point", "day_left_then_day_right"}}) {
      StatusOr<placerec::Run> run = LoadRun(root + "/" + dataset, run_name);
      if (!run.ok()) {
        *why = "needs the shared evaluation data (set PLACEREC_DATA): " + run.status().ToString();
        return false;
      }
      for (const RunFrame& frame : run->frames) {
        StatusOr<EncodedImage> image = EncodeImageFile(frame.image);
        if (!image.ok()) {
          *why = image.status().ToString();
          return false;
        }
        images->push_back(std::move(*image));
      }
    }
    return true;
  }

  // Empties the map's write-ahead log (a TRUNCATE checkpoint through a connection of our own,
  // as any SQLite process may make), so that the next insert after the disk fills must grow
  // it: without this the log's reusable pages can take a few megabytes of inserts on a full
  // disk. True when the log is empty afterwards.
  bool TruncateWriteAheadLog() {
    sqlite3* db = nullptr;
    bool truncated = false;
    if (sqlite3_open_v2(db_.c_str(), &db, SQLITE_OPEN_READWRITE, nullptr) == SQLITE_OK) {
      sqlite3_busy_timeout(db, 5000);
      truncated = sqlite3_exec(db, "PRAGMA wal_checkpoint(TRUNCATE)", nullptr, nullptr, nullptr) ==
                  SQLITE_OK;
    }
    sqlite3_close(db);
    struct stat wal = {};
    return truncated && stat((db_ + "-wal").c_str(), &wal) == 0 && wal.st_size == 0;
  }

  // Fills the map's file system: a file of zeros written until the disk is full.
  std::string FillDisk() {
    const std::string filler = map_dir_ + "/filler";
    const int fd = open(filler.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    EXPECT_GE(fd, 0) << std::strerror(errno);
    const std::vector<char> chunk(1 << 20, 0);
    while (fd >= 0 && write(fd, chunk.data(), chunk.size()) > 0) {
    }
    // The last pages of a not quite full chunk, so that nothing is left.
    while (fd >= 0 && write(fd, chunk.data(), 4096) > 0) {
    }
    if (fd >= 0) close(fd);
    return filler;
  }

  std::string dir_;
  std::string map_dir_;
  std::string db_;
  std::unique_ptr<ChildProcess> server_;
};

TEST_F(SoakTest, EightRobotsWithARestartAndAFullDisk) {
  std::vector<EncodedImage> images;
  std::string why;
  if (!LoadImages(&images, &why)) GTEST_SKIP() << why;
  const double duration_s = SoakSeconds();
  const double disk_full_s = std::max(10.0, kDiskFullFor * duration_s);

  const std::string keys = testing_service::WriteTestKeys(dir_ + "/keys", {{"robots", "both"}});
  ClientOptions options;
  options.lcm_url = TestLcmUrl();
  options.key_file = keys;
  options.timeout_s = 180;
  options.retry_after_s = 5;
  StatusOr<std::unique_ptr<PlacerecClient>> connected = PlacerecClient::Connect(options);
  ASSERT_TRUE(connected.ok()) << connected.status().ToString();
  PlacerecClient* client = connected->get();
  AnswerCounter counter;
  ASSERT_TRUE(counter.good());

  StatusOr<std::unique_ptr<ChildProcess>> started =
      StartServer(db_, {"--keys", keys}, dir_ + "/server.log", client);
  ASSERT_TRUE(started.ok()) << started.status().ToString();
  server_ = std::move(*started);
  std::atomic<pid_t> server_pid{server_->pid()};

  const Clock::time_point start = Clock::now();
  std::atomic<int> phase{static_cast<int>(Phase::kMixed)};
  std::atomic<bool> stop{false};
  std::atomic<int> storage_errors_seen{0};  // answers "storage error" so far
  std::atomic<bool> paused{false};          // robots hold their next frames
  std::atomic<int> in_flight{0};            // frames sent and not yet answered

  // Memory, once a second.
  std::vector<MemorySample> memory;
  std::thread sampler([&] {
    while (!stop) {
      const pid_t pid = server_pid;
      const int64_t rss = pid > 0 ? ResidentKib(pid) : 0;
      // Busy samples only: the idle readings are taken apart (idle_rss_kib).
      if (rss > 0 && !paused) {
        memory.push_back({SecondsSince(start), static_cast<Phase>(phase.load()), rss});
      }
      std::this_thread::sleep_for(std::chrono::seconds(1));
    }
  });

  // The robots.
  std::mutex sent_mutex;
  std::vector<SentFrame> sent;
  std::vector<std::thread> robots;
  // Joins every thread however the test leaves (a failed ASSERT returns early).
  struct Joiner {
    std::atomic<bool>* stop;
    std::vector<std::thread>* threads;
    std::thread* sampler;
    ~Joiner() {
      *stop = true;
      for (std::thread& t : *threads) {
        if (t.joinable()) t.join();
      }
      if (sampler->joinable()) sampler->join();
    }
  } joiner{&stop, &robots, &sampler};
  for (int r = 0; r < kRobots; ++r) {
    robots.emplace_back([&, r] {
      const std::string robot = "soak" + std::to_string(r);
      int64_t sequence = 0;
      for (int64_t k = 0; !stop; ++k) {
        // The frame counts as in flight before `paused` is read: whoever pauses the robots and
        // then finds no frame in flight knows that no robot is about to send one.
        ++in_flight;
        while (paused && !stop) {
          --in_flight;
          std::this_thread::sleep_for(std::chrono::milliseconds(20));
          ++in_flight;
        }
        const double t = SecondsSince(start);
        if (t >= duration_s) {
          --in_flight;
          break;
        }
        OutgoingFrame frame;
        frame.robot = robot;
        frame.insert = t < kQueryOnlyFrom * duration_s && k % 3 != 2;
        frame.sequence = frame.insert ? sequence++ : k;
        frame.utime = 1'700'000'000'000'000 + k * 100'000;
        frame.image = images[(r * 97 + k) % images.size()];
        SentFrame record;
        record.robot = robot;
        record.sequence = frame.sequence;
        record.insert = frame.insert;
        record.sent_s = t;
        StatusOr<PendingFrame> pending = client->Publish(frame);
        if (!pending.ok()) {
          record.result.code = AnswerCode::kNotSent;
          record.result.message = pending.status().ToString();
        } else {
          record.request_id = pending->request_id;
          record.result = client->Wait(*pending, options.timeout_s);
        }
        --in_flight;
        if (record.result.code == AnswerCode::kStorageError) ++storage_errors_seen;
        std::lock_guard lock(sent_mutex);
        sent.push_back(std::move(record));
      }
    });
  }

  auto sleep_until = [&](double t_s) {
    while (SecondsSince(start) < t_s) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  };
  // The disk-full episode.
  sleep_until(kDiskFullAt * duration_s);
  phase = static_cast<int>(Phase::kDiskFull);
  const double disk_full_begin = SecondsSince(start);
  const bool wal_truncated = TruncateWriteAheadLog();
  const std::string filler = FillDisk();
  struct stat wal_stat = {};
  const int64_t wal_bytes_at_disk_full =
      stat((db_ + "-wal").c_str(), &wal_stat) == 0 ? wal_stat.st_size : -1;
  sleep_until(disk_full_begin + disk_full_s);
  while (storage_errors_seen == 0 && SecondsSince(start) < kKillAt * duration_s - 5) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_EQ(unlink(filler.c_str()), 0);
  const double disk_full_end = SecondsSince(start);
  phase = static_cast<int>(Phase::kMixed);

  // SIGKILL and restart.
  sleep_until(kKillAt * duration_s);
  phase = static_cast<int>(Phase::kRestart);
  const double kill_at = SecondsSince(start);
  server_pid = 0;
  server_->Signal(SIGKILL);
  StatusOr<int> killed = server_->Wait(30);
  ASSERT_TRUE(killed.ok());
  EXPECT_EQ(*killed, 128 + SIGKILL);
  server_.reset();
  started = StartServer(db_, {"--keys", keys}, dir_ + "/server2.log", client);
  ASSERT_TRUE(started.ok()) << started.status().ToString();
  server_ = std::move(*started);
  server_pid = server_->pid();
  const double restart_s = SecondsSince(start) - kill_at;
  phase = static_cast<int>(Phase::kMixed);

  sleep_until(kQueryOnlyFrom * duration_s);
  phase = static_cast<int>(Phase::kQueryOnly);
  const double query_only_begin = SecondsSince(start);
  // Resident memory of the idle server: every frame answered, the server's log saying it gave
  // its free heap memory back since the robots were paused, then the least of three readings;
  // 0 when the server never said so.
  auto idle_rss_kib = [&]() {
    const int trimmed_before = CountLinesWith(server_->log_path(), kTrimmedLine);
    paused = true;
    while (in_flight > 0) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    const double waited_from = SecondsSince(start);
    while (CountLinesWith(server_->log_path(), kTrimmedLine) == trimmed_before) {
      if (SecondsSince(start) - waited_from > kTrimWaitSeconds) {
        paused = false;
        return 0.0;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
    int64_t least = std::numeric_limits<int64_t>::max();
    for (int i = 0; i < 3; ++i) {
      least = std::min(least, ResidentKib(server_pid));
      std::this_thread::sleep_for(std::chrono::milliseconds(300));
    }
    paused = false;
    return static_cast<double>(least);
  };
  sleep_until(query_only_begin + kTailSettleShare * (duration_s - query_only_begin));
  const double early = idle_rss_kib();
  for (std::thread& robot : robots) robot.join();
  const double late = idle_rss_kib();
  stop = true;
  sampler.join();
  std::this_thread::sleep_for(std::chrono::seconds(1));  // the last answers reach the counter
  StatusOr<int> stopped = StopServer(server_.get());
  ASSERT_TRUE(stopped.ok()) << stopped.status().ToString();
  EXPECT_EQ(*stopped, 0) << Tail(server_->log_path());
  server_.reset();

  // Every frame processed exactly once: answered, and any further answer a copy of the first
  // (a re-sent frame answered from the record). The only failures are inserts during the
  // disk-full episode (allowing for the frames then in flight).
  const auto published = counter.published();
  std::map<std::string, int> by_code;
  int not_once = 0, answered_again = 0, storage_errors = 0, stored_after_disk_full = 0,
      other_failures = 0;
  std::vector<double> latency_ms[4];
  for (const SentFrame& frame : sent) {
    ++by_code[AnswerCodeName(frame.result.code)];
    const auto it = published.find({frame.robot, frame.request_id});
    const std::vector<Publication> none;
    const std::vector<Publication>& answers = it == published.end() ? none : it->second;
    const bool copies = std::all_of(answers.begin(), answers.end(),
                                    [&](const Publication& p) { return p == answers.front(); });
    if (answers.empty() || !copies) {
      ++not_once;
      ADD_FAILURE() << frame.robot << " request " << frame.request_id << " answered "
                    << answers.size() << " times" << (copies ? "" : ", not all alike");
    }
    if (answers.size() > 1 && copies) ++answered_again;
    const bool in_episode =
        frame.sent_s >= disk_full_begin - 10 && frame.sent_s < disk_full_end + 10;
    if (frame.result.code == AnswerCode::kStorageError && frame.insert && in_episode) {
      ++storage_errors;
    } else if (!frame.result.ok()) {
      ++other_failures;
      ADD_FAILURE() << frame.robot << " sequence " << frame.sequence << " at " << frame.sent_s
                    << " s: " << DescribeResult(frame.result);
    }
    if (frame.insert && frame.result.ok() && frame.result.place_id >= 0 &&
        frame.sent_s > disk_full_end) {
      ++stored_after_disk_full;
    }
    if (frame.result.ok()) {
      const Phase p = frame.sent_s >= query_only_begin ? Phase::kQueryOnly
                      : frame.sent_s >= kill_at && frame.sent_s < kill_at + restart_s
                          ? Phase::kRestart
                      : in_episode ? Phase::kDiskFull
                                   : Phase::kMixed;
      latency_ms[static_cast<int>(p)].push_back(frame.result.latency_ms);
    }
  }
  EXPECT_GT(storage_errors, 0) << "the full disk refused no insert";
  EXPECT_GT(stored_after_disk_full, 0) << "no insert was stored after the disk was freed";

  // Every acknowledged insert's place, with its landmarks, is in the map.
  std::map<std::pair<std::string, int64_t>, Place> stored;
  {
    SqliteStoreOptions store_options;
    store_options.must_exist = true;
    StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(db_, store_options);
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    ASSERT_TRUE((*store)
                    ->LoadPlaces([&](const Place& p) {
                      stored[{p.robot, p.sequence}] = p;
                    })
                    .ok());
  }
  int acknowledged = 0, lost = 0;
  int64_t acknowledged_landmarks = 0;
  for (const SentFrame& frame : sent) {
    if (!frame.insert || !frame.result.ok() || frame.result.place_id < 0) continue;
    ++acknowledged;
    acknowledged_landmarks += frame.result.landmarks;
    const auto it = stored.find({frame.robot, frame.sequence});
    if (it == stored.end() || it->second.id.value() != frame.result.place_id ||
        it->second.num_landmarks != frame.result.landmarks) {
      ++lost;
      ADD_FAILURE() << "acknowledged place of " << frame.robot << " sequence " << frame.sequence
                    << " is not in the map as acknowledged";
    }
  }
  EXPECT_GT(acknowledged, kRobots);

  // Memory during the query-only phase, after it settled: what the idle server holds early in
  // it and at its end (with frames in work resident memory saw-tooths by tens of MiB, a frame's
  // working set, so busy readings say little). Retained memory raises the second reading. The
  // least-squares slope of the once-a-second samples is reported too.
  ASSERT_GT(early, 0) << "the idle server did not log that it trimmed its heap, or its memory "
                         "could not be read: "
                      << Tail(server_->log_path());
  ASSERT_GT(late, 0) << "the idle server did not log that it trimmed its heap at the end, or its "
                        "memory could not be read: "
                     << Tail(server_->log_path());
  std::vector<MemorySample> tail;
  const double settle_until = query_only_begin + kTailSettleShare * (duration_s - query_only_begin);
  for (const MemorySample& s : memory) {
    if (s.t_s >= settle_until) tail.push_back(s);
  }
  double mean_t = 0, mean_rss = 0;
  for (const MemorySample& s : tail) {
    mean_t += s.t_s / tail.size();
    mean_rss += static_cast<double>(s.rss_kib) / tail.size();
  }
  double covariance = 0, variance = 0;
  for (const MemorySample& s : tail) {
    covariance += (s.t_s - mean_t) * (static_cast<double>(s.rss_kib) - mean_rss);
    variance += (s.t_s - mean_t) * (s.t_s - mean_t);
  }
  const double slope_mib_per_hour = variance > 0 ? covariance / variance * 3600 / 1024 : 0;
  EXPECT_LE(late - early, std::max(0.03 * early, 16.0 * 1024))
      << "the idle server's resident memory grew from " << early << " to " << late
      << " KiB on an unchanging map";

  int64_t rss_max = 0;
  for (const MemorySample& s : memory) rss_max = std::max(rss_max, s.rss_kib);
  nlohmann::json report;
  report["duration_s"] = duration_s;
  report["robots"] = kRobots;
  report["frames"] = sent.size();
  report["answers_by_code"] = by_code;
  report["frames_not_processed_exactly_once"] = not_once;
  report["frames_answered_again_from_the_record"] = answered_again;
  report["storage_errors_during_disk_full"] = storage_errors;
  report["other_failures"] = other_failures;
  report["disk_full_s"] = {disk_full_begin, disk_full_end};
  report["wal_bytes_at_disk_full"] = wal_bytes_at_disk_full;
  report["wal_truncated_before_disk_full"] = wal_truncated;
  report["kill_at_s"] = kill_at;
  report["restart_s"] = restart_s;
  report["acknowledged_places"] = acknowledged;
  report["acknowledged_landmarks"] = acknowledged_landmarks;
  report["acknowledged_places_lost"] = lost;
  report["map_places"] = stored.size();
  report["rss_max_mib"] = rss_max / 1024.0;
  report["query_only_idle_rss_mib"] = {early / 1024.0, late / 1024.0};
  report["query_only_rss_slope_mib_per_hour"] = slope_mib_per_hour;
  report["frames_per_second"] = sent.size() / duration_s;
  for (int p = 0; p < 4; ++p) {
    const char* name = PhaseName(static_cast<Phase>(p));
    report["latency_ms"][name] = {{"frames", latency_ms[p].size()},
                                  {"p50", Percentile(latency_ms[p], 50)},
                                  {"p95", Percentile(latency_ms[p], 95)}};
  }
  std::cout << report.dump(2) << "\n";
  if (const char* out = std::getenv("PLACEREC_SOAK_OUT"); out != nullptr && *out != '\0') {
    std::ofstream(std::string(out) + "/soak.json") << report.dump(2) << "\n";
    std::ofstream csv(std::string(out) + "/memory.csv");
    csv << "t_s,phase,rss_kib\n";
    for (const MemorySample& s : memory) {
      csv << s.t_s << "," << PhaseName(s.phase) << "," << s.rss_kib << "\n";
    }
  }
}

}  // namespace
}  // namespace placerec
