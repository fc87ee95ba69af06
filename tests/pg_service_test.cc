// Several placerec-servers on one PostgreSQL map (issue 24 item 4), each test in its own private
// network namespace (tests/service_harness.h) with its own throw-away cluster (scripts/pg.sh):
// a place inserted through one server is found through another within a second; a server killed
// mid-stream loses no acknowledged place and a server started late loads the whole map and takes
// its robots over; the database stopped and started again gives storage-error answers, then
// recovery on every server. The robots are split between the servers with --robots. Tests skip
// with a message when not root (no namespace), when ../shared/data is missing, or when the
// PostgreSQL binaries are missing.
#include <signal.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "client/client.h"
#include "common/eval/run.h"
#include "common/storage/postgres_store.h"
#include "common/storage/postgres_testing.h"
#include "common/util/paths.h"
#include "tests/service_harness.h"

namespace placerec {
namespace {

using testing_postgres::TestCluster;
using testing_service::BinaryPath;
using testing_service::ChildProcess;
using testing_service::MakeTempDir;
using testing_service::ReadTextFile;
using testing_service::RemoveTempDir;
using testing_service::Tail;
using testing_service::TestLcmUrl;
using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

class PostgresServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string dataset = DataDir("", PLACEREC_DEFAULT_DATA_DIR) + "/rtabmap_indoor";
    if (!PathExists(dataset + "/runs/corridor_loop.frames.csv")) {
      GTEST_SKIP() << "needs " << dataset << " (the shared evaluation data); set PLACEREC_DATA";
    }
    const Status network = testing_service::EnterPrivateNetwork();
    if (!network.ok()) GTEST_SKIP() << "server tests skipped: " << network.message();
    StatusOr<std::unique_ptr<TestCluster>> cluster =
        TestCluster::Start(std::string(PLACEREC_SOURCE_DIR) + "/scripts/pg.sh");
    if (!cluster.ok() && cluster.status().code() == StatusCode::kNotFound) {
      GTEST_SKIP() << cluster.status().message();
    }
    ASSERT_TRUE(cluster.ok()) << cluster.status().ToString();
    cluster_ = std::move(*cluster);
    url_ = cluster_->Url();
    StatusOr<placerec::Run> run = LoadRun(dataset, "corridor_loop");
    ASSERT_TRUE(run.ok()) << run.status().ToString();
    run_ = std::move(*run);
    dir_ = MakeTempDir("placerec_pg_service_");
    ASSERT_FALSE(dir_.empty());
    keys_ = testing_service::WriteTestKeys(dir_ + "/keys", {{"robots", "both"}});
    ClientOptions options;
    options.lcm_url = TestLcmUrl();
    options.key_file = keys_;
    options.timeout_s = 60;
    StatusOr<std::unique_ptr<PlacerecClient>> client = PlacerecClient::Connect(options);
    ASSERT_TRUE(client.ok()) << client.status().ToString();
    client_ = std::move(*client);
  }

  void TearDown() override {
    servers_.clear();
    client_.reset();
    cluster_.reset();
    RemoveTempDir(dir_);
  }

  // Starts server `name` on the map answering `robots`, and waits until it serves (its log says
  // so: other servers' heartbeats cannot tell one server's start from another's).
  ChildProcess* StartServer(const std::string& name, const std::string& robots, int workers = 1) {
    const std::string log = dir_ + "/" + name + ".log";
    StatusOr<std::unique_ptr<ChildProcess>> server = ChildProcess::Start(
        {BinaryPath("placerec-server"), "--db", url_, "--lcm-url", TestLcmUrl(), "--keys", keys_,
         "--robots", robots, "--workers", std::to_string(workers), "--status-period", "0.05"},
        log);
    EXPECT_TRUE(server.ok()) << server.status().ToString();
    if (!server.ok()) return nullptr;
    const auto start = Clock::now();
    while (SecondsSince(start) < 60) {
      if (!(*server)->running()) {
        ADD_FAILURE() << "server " << name << " exited at start-up\n" << Tail(log);
        return nullptr;
      }
      if (ReadTextFile(log).find("] placerec-server ") != std::string::npos) {
        ChildProcess* raw = server->get();
        servers_[name] = std::move(*server);
        return raw;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    ADD_FAILURE() << "server " << name << " did not start within 60 s\n" << Tail(log);
    return nullptr;
  }

  std::string Logs() const {
    std::string logs;
    for (const auto& [name, server] : servers_) logs += Tail(server->log_path(), 15);
    return logs;
  }

  OutgoingFrame FrameOf(int f, const std::string& robot, int64_t sequence, bool insert) const {
    OutgoingFrame frame;
    frame.robot = robot;
    frame.sequence = sequence;
    frame.utime = run_.frames[f].utime;
    frame.insert = insert;
    StatusOr<EncodedImage> image = EncodeImageFile(run_.frames[f].image);
    EXPECT_TRUE(image.ok()) << image.status().ToString();
    if (image.ok()) frame.image = std::move(*image);
    return frame;
  }

  // The answer to frame f sent query-only as `robot`.
  FrameResult Query(int f, const std::string& robot) {
    const FrameResult r = client_->Send(FrameOf(f, robot, f, /*insert=*/false));
    EXPECT_TRUE(r.ok()) << robot << " " << f << ": " << DescribeResult(r) << Logs();
    return r;
  }

  // Whether the query of frame f by the device (served by the second server) lists `place`;
  // `latency_ms` receives the time from publishing the query to its answer.
  bool QueryFinds(int f, int64_t place, double* latency_ms = nullptr) {
    const FrameResult r = client_->Send(FrameOf(f, "device", f, /*insert=*/false));
    EXPECT_TRUE(r.ok()) << DescribeResult(r) << Logs();
    if (latency_ms != nullptr) *latency_ms = r.latency_ms;
    for (const MatchedPlace& match : r.matches) {
      if (match.place_id == place) return true;
    }
    return false;
  }

  // Every place of the map, read straight from the database.
  std::vector<Place> MapPlaces() const {
    std::vector<Place> places;
    StatusOr<std::unique_ptr<LandmarkStore>> store = OpenPostgresStore(url_, {});
    EXPECT_TRUE(store.ok()) << store.status().ToString();
    if (!store.ok()) return places;
    EXPECT_TRUE((*store)->LoadPlaces([&](const Place& place) { places.push_back(place); }).ok());
    return places;
  }

  // The next heartbeat's place count once only the server reporting it runs.
  int64_t HeartbeatPlaces() {
    StatusOr<ServerStatus> status = client_->WaitForStatus(10);
    EXPECT_TRUE(status.ok()) << status.status().ToString();
    return status.ok() ? status->map_places : -1;
  }

  std::unique_ptr<TestCluster> cluster_;
  std::string url_;
  placerec::Run run_;
  std::string dir_;
  std::string keys_;
  std::unique_ptr<PlacerecClient> client_;
  std::map<std::string, std::unique_ptr<ChildProcess>> servers_;
};

// Robot A inserts through server 1. After each acknowledgement, server 2's heartbeats (every
// 50 ms) must count the new place within 1 s, and a device served by server 2 that queries the
// same image finds it. The two servers' heartbeats are told apart by their worker counts. At the
// end the same queries through server 1, server 2 and a server started on the finished map get
// the same answers (every server indexes the places in id order).
TEST_F(PostgresServiceTest, APlaceInsertedThroughOneServerIsFoundThroughAnotherWithinASecond) {
  ASSERT_NE(StartServer("one", "robotA,probe1", /*workers=*/1), nullptr);
  ASSERT_NE(StartServer("two", "device", /*workers=*/2), nullptr);
  constexpr int kFrames = 14;
  int places = 0;
  int found = 0;
  std::vector<double> delays_ms;  // acknowledgement to server 2's heartbeat counting the place
  for (int f = 0; f < kFrames; ++f) {
    const FrameResult inserted = client_->Send(FrameOf(f, "robotA", f, /*insert=*/true));
    ASSERT_TRUE(inserted.ok()) << f << ": " << DescribeResult(inserted) << Logs();
    if (inserted.place_id < 0) continue;
    ++places;
    const auto acknowledged = Clock::now();
    bool counted = false;
    while (!counted && SecondsSince(acknowledged) < 3.0) {
      StatusOr<ServerStatus> status = client_->WaitForStatus(1.0);
      counted = status.ok() && status->workers == 2 && status->map_places >= places;
    }
    const double delay_ms = 1000 * SecondsSince(acknowledged);
    ASSERT_TRUE(counted) << "server two did not count place " << inserted.place_id << " within 3 s"
                         << Logs();
    EXPECT_LT(delay_ms, 1000) << "place " << inserted.place_id;
    delays_ms.push_back(delay_ms);
    if (QueryFinds(f, inserted.place_id)) ++found;
  }
  ASSERT_GT(places, 3) << "too few frames stored a place to test anything";
  EXPECT_GT(found, places / 2) << "server two's queries found few of server one's places";
  std::sort(delays_ms.begin(), delays_ms.end());
  std::printf(
      "%d places through server one, counted by server two after median %.0f ms, max "
      "%.0f ms (heartbeats every 50 ms); %d found by server two's query of the same "
      "image\n",
      places, delays_ms[delays_ms.size() / 2], delays_ms.back(), found);
  RecordProperty("places", std::to_string(places));
  RecordProperty("max_delay_ms", std::to_string(delays_ms.back()));
  // Both servers' maps equal the database's.
  EXPECT_EQ(static_cast<int64_t>(MapPlaces().size()), places);
  // The same answers through every server, and through one that loads the map now.
  ASSERT_NE(StartServer("three", "probe3"), nullptr);
  int compared = 0;
  for (int f = 1; f < kFrames; f += 3) {
    const FrameResult two = Query(f, "device");
    for (const char* robot : {"probe1", "probe3"}) {
      const FrameResult other = Query(f, robot);
      ASSERT_EQ(other.matches.size(), two.matches.size()) << robot << " frame " << f;
      for (size_t i = 0; i < two.matches.size(); ++i) {
        EXPECT_EQ(other.matches[i].place_id, two.matches[i].place_id) << robot << " " << f;
        EXPECT_EQ(other.matches[i].score, two.matches[i].score) << robot << " " << f;
        EXPECT_EQ(other.matches[i].matched_landmarks, two.matches[i].matched_landmarks);
      }
      EXPECT_EQ(other.loop_closure, two.loop_closure) << robot << " " << f;
      compared += static_cast<int>(two.matches.size());
    }
  }
  EXPECT_GT(compared, 0);
  for (auto& [name, server] : servers_) {
    server->Signal(SIGTERM);
    StatusOr<int> code = server->Wait(60);
    ASSERT_TRUE(code.ok());
    EXPECT_EQ(*code, 0) << Tail(server->log_path());
  }
}

// Server 1 is killed (SIGKILL) while robot A streams frames through it: every acknowledged place
// is in the database, and server 2 holds them all. A third server started afterwards loads the
// whole map and takes robot A over: its next frames are accepted and recognised.
TEST_F(PostgresServiceTest, AKilledServerLosesNothingAndALateServerLoadsTheWholeMap) {
  ChildProcess* one = StartServer("one", "robotA");
  ASSERT_NE(one, nullptr);
  ASSERT_NE(StartServer("two", "device"), nullptr);
  constexpr int kAcknowledged = 16;
  constexpr int kWindow = 4;  // frames in flight when the server dies
  std::vector<PendingFrame> pending;
  std::vector<FrameResult> acked;
  int next = 0;
  while (static_cast<int>(acked.size()) < kAcknowledged) {
    while (static_cast<int>(pending.size()) - static_cast<int>(acked.size()) < kWindow) {
      StatusOr<PendingFrame> p = client_->Publish(FrameOf(next, "robotA", next, true));
      ASSERT_TRUE(p.ok()) << p.status().ToString();
      ++next;
      pending.push_back(*p);
    }
    FrameResult r = client_->Wait(pending[acked.size()], 60);
    ASSERT_TRUE(r.ok()) << DescribeResult(r) << Logs();
    acked.push_back(std::move(r));
  }
  one->Signal(SIGKILL);
  StatusOr<int> killed = one->Wait(30);
  ASSERT_TRUE(killed.ok());
  EXPECT_EQ(*killed, 128 + SIGKILL);
  servers_.erase("one");

  std::map<int64_t, Place> stored;  // by sequence
  for (const Place& place : MapPlaces()) stored[place.sequence] = place;
  int acked_places = 0;
  for (const FrameResult& r : acked) {
    if (r.place_id < 0) continue;
    ++acked_places;
    ASSERT_EQ(stored.count(r.sequence), 1u) << "acknowledged frame " << r.sequence << " lost";
    EXPECT_EQ(stored[r.sequence].id.value(), r.place_id);
    EXPECT_EQ(stored[r.sequence].num_landmarks, r.landmarks);
  }
  ASSERT_GT(acked_places, 3);
  // Server 2 (now the only one sending heartbeats) holds every stored place within a second.
  const auto killed_at = Clock::now();
  int64_t seen = -1;
  while (SecondsSince(killed_at) < 1.0 && seen != static_cast<int64_t>(stored.size())) {
    seen = HeartbeatPlaces();
  }
  EXPECT_EQ(seen, static_cast<int64_t>(stored.size())) << Logs();

  // A server started late loads the whole map and serves robot A from where it was.
  servers_["two"]->Signal(SIGTERM);
  ASSERT_TRUE(servers_["two"]->Wait(60).ok());
  servers_.erase("two");
  ASSERT_NE(StartServer("three", "robotA,device"), nullptr);
  EXPECT_EQ(HeartbeatPlaces(), static_cast<int64_t>(stored.size())) << Logs();
  int64_t map_places = static_cast<int64_t>(stored.size());
  const int last_stored = static_cast<int>(stored.rbegin()->first);
  int recognised = 0;
  for (int f = last_stored + 1; f < last_stored + 9; ++f) {
    const FrameResult r = client_->Send(FrameOf(f, "robotA", f, true));
    ASSERT_TRUE(r.ok()) << f << ": " << DescribeResult(r) << Logs();
    EXPECT_EQ(r.map_places, map_places + (r.place_id >= 0 ? 1 : 0));
    map_places = r.map_places;
    if (!r.matches.empty()) ++recognised;
  }
  EXPECT_GT(recognised, 0) << "the late server matched nothing of the map it loaded";
  EXPECT_EQ(static_cast<int64_t>(MapPlaces().size()), map_places);
}

// The database stops: inserts that would store a place are answered with a storage error (and
// nothing else breaks: the servers run on, queries are answered from memory); once it is back the
// robot's frames are stored again, and the other server, whose follower reconnected, has them.
TEST_F(PostgresServiceTest, ADatabaseOutageGivesStorageErrorsThenRecovery) {
  ChildProcess* one = StartServer("one", "robotA");
  ChildProcess* two = StartServer("two", "device", /*workers=*/2);
  ASSERT_NE(one, nullptr);
  ASSERT_NE(two, nullptr);
  int f = 0;
  int places = 0;
  for (; f < 6; ++f) {
    const FrameResult r = client_->Send(FrameOf(f, "robotA", f, true));
    ASSERT_TRUE(r.ok()) << f << ": " << DescribeResult(r) << Logs();
    if (r.place_id >= 0) ++places;
  }
  ASSERT_TRUE(cluster_->Down());
  // Frames that show nothing new store nothing and are answered ok; the first that would store a
  // place gets the storage error.
  FrameResult refused;
  for (; f < 30; ++f) {
    refused = client_->Send(FrameOf(f, "robotA", f, true));
    if (refused.code != AnswerCode::kOk) break;
    ASSERT_LT(refused.place_id, 0);
  }
  ASSERT_EQ(refused.code, AnswerCode::kStorageError) << DescribeResult(refused) << Logs();
  EXPECT_LT(refused.place_id, 0);
  const FrameResult query = client_->Send(FrameOf(2, "device", 2, false));
  EXPECT_TRUE(query.ok()) << DescribeResult(query);
  EXPECT_TRUE(one->running());
  EXPECT_TRUE(two->running());

  ASSERT_TRUE(cluster_->Up());
  // The refused frame again (the server retries the connection), then the next frames until one
  // stores a place.
  const auto back = Clock::now();
  FrameResult stored;
  while (SecondsSince(back) < 10) {
    stored = client_->Send(FrameOf(f, "robotA", f, true));
    if (stored.code == AnswerCode::kStorageError) {
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
      continue;
    }
    ASSERT_TRUE(stored.ok()) << DescribeResult(stored) << Logs();
    if (stored.place_id >= 0 || ++f >= 40) break;
  }
  ASSERT_TRUE(stored.ok()) << DescribeResult(stored) << Logs();
  ASSERT_GE(stored.place_id, 0) << "no frame stored a place after the database came back";
  EXPECT_EQ(stored.map_places, places + 1);
  // Server 2's follower reconnects (retrying every 0.5 s) and catches up: its heartbeats (told
  // apart by its worker count) count the new place.
  bool counted = false;
  const auto acknowledged = Clock::now();
  while (!counted && SecondsSince(acknowledged) < 3.0) {
    StatusOr<ServerStatus> status = client_->WaitForStatus(1.0);
    counted = status.ok() && status->workers == 2 && status->map_places == places + 1;
  }
  EXPECT_TRUE(counted) << Logs();
  EXPECT_NE(ReadTextFile(two->log_path()).find("map follower reconnected"), std::string::npos)
      << Logs();
  EXPECT_EQ(static_cast<int64_t>(MapPlaces().size()), places + 1);
}

}  // namespace
}  // namespace placerec
