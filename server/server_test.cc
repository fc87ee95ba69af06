// Tests of the server's in-process side (server.h): option checks, what Create refuses and why,
// the map it serves (reloaded from its file) as its heartbeat reports it, and Run ending on
// Stop. LCM is memq://, which keeps messages inside the process; frames over the network are
// tests/service_test.cc's, each test in a private network namespace.
#include "server/server.h"

#include <sched.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <future>
#include <iterator>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "common/pipeline/place_map.h"
#include "common/storage/sqlite_store.h"
#include "common/util/options_test_util.h"

namespace placerec {
namespace {

// A fresh directory for one test's files, removed afterwards; of this process's own, since other
// runs of the suite on the machine share the temp folder.
class TempDir {
 public:
  explicit TempDir(const std::string& name)
      : path_(std::filesystem::path(::testing::TempDir()) /
              ("placerec_server_" + name + "_" + std::to_string(getpid()))) {
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  std::string File(const std::string& name) const { return (path_ / name).string(); }

 private:
  std::filesystem::path path_;
};

// Options for a server on `db` that needs no network (memq://) and no trained models.
ServerOptions TestOptions(const std::string& db) {
  ServerOptions options;
  options.db_path = db;
  options.lcm_urls = {"memq://"};
  options.recognizer.analyzer.segmentation = SegmentationMethod::kSuperpixels;
  // These tests are about the map and the serving loop in one process, where no frame arrives
  // from outside; authentication has its own tests (authenticator_test.cc, the service tests).
  options.auth.enabled = false;
  return options;
}

// A landmark of `rows` random descriptors, one keypoint each.
Landmark RandomLandmark(int rows, std::mt19937* rng) {
  std::uniform_int_distribution<int> byte(0, 255);
  Landmark landmark;
  landmark.sift_count = rows;
  landmark.box = cv::Rect(0, 0, 10, 10);
  landmark.descriptors.create(rows, 128, CV_8U);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < 128; ++c) {
      landmark.descriptors.at<uint8_t>(r, c) = static_cast<uint8_t>(byte(*rng));
    }
    landmark.keypoints.emplace_back(cv::Point2f(static_cast<float>(r), 0.0f), 3.0f);
  }
  return landmark;
}

// Writes a map of two places (landmarks of 10 and 15 descriptors; one of 5) to `db`.
void WriteMap(const std::string& db) {
  StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(db, SqliteStoreOptions());
  ASSERT_TRUE(store.ok()) << store.status().ToString();
  StatusOr<std::unique_ptr<PlaceMap>> map =
      PlaceMap::Open(std::move(*store), LandmarkIndexOptions());
  ASSERT_TRUE(map.ok()) << map.status().ToString();
  std::mt19937 rng(51);
  Place first{PlaceId(), "robot", 0, 1000000, 0, 320};
  std::vector<Landmark> two = {RandomLandmark(10, &rng), RandomLandmark(15, &rng)};
  ASSERT_TRUE((*map)->Insert(&first, &two).ok());
  Place second{PlaceId(), "robot", 1, 2000000, 0, 320};
  std::vector<Landmark> one = {RandomLandmark(5, &rng)};
  ASSERT_TRUE((*map)->Insert(&second, &one).ok());
}

TEST(ServerOptionsTest, DefaultsPassAndBadValuesNameTheirFlag) {
  std::string error;
  EXPECT_TRUE(ServerOptions().Check(&error)) << error;
  options_test::ExpectEachRefusedByName<ServerOptions>({
      {"--db", [](ServerOptions* o) { o->db_path.clear(); }},
      {"--workers", [](ServerOptions* o) { o->workers = -1; }},
      {"--workers", [](ServerOptions* o) { o->workers = 257; }},
      {"--queue", [](ServerOptions* o) { o->queue_capacity = 0; }},
      {"--status-period", [](ServerOptions* o) { o->status_period_s = 0; }},
      {"--status-period", [](ServerOptions* o) { o->status_period_s = -1; }},
      {"--status-period",
       [](ServerOptions* o) { o->status_period_s = std::numeric_limits<double>::quiet_NaN(); }},
      {"--status-period",
       [](ServerOptions* o) { o->status_period_s = std::numeric_limits<double>::infinity(); }},
      {"--robot-restart-gap", [](ServerOptions* o) { o->sequence_rule.restart_gap_s = -1; }},
      {"--robot-restart-gap",
       [](ServerOptions* o) {
         o->sequence_rule.restart_gap_s = std::numeric_limits<double>::quiet_NaN();
       }},
      {"--max-robot-runs", [](ServerOptions* o) { o->sequence_rule.max_robot_runs = 0; }},
      // The parts' own checks run too.
      {"--auth-window", [](ServerOptions* o) { o->auth.window_s = 0; }},
      {"max_image_width", [](ServerOptions* o) { o->recognizer.analyzer.max_image_width = 10; }},
      {"connect_timeout_s", [](ServerOptions* o) { o->postgres.connect_timeout_s = 0; }},
      {"insert_timeout_ms", [](ServerOptions* o) { o->postgres.insert_timeout_ms = 0; }},
      {"--robots",
       [](ServerOptions* o) {
         o->robots = {"r1", ""};
       }},
      {"--repair",
       [](ServerOptions* o) {
         o->db_path = "postgresql:///placerec";
         o->repair = true;
       }},
  });
  // The edges are allowed.
  ServerOptions edges;
  edges.workers = 256;
  edges.queue_capacity = 1;
  EXPECT_TRUE(edges.Check(&error)) << error;
}

// Create refuses, with a message saying what is wrong, options that do not check, a segmenter
// without its models, a file that is not a map (left untouched) and an LCM URL that does not
// open.
TEST(ServerTest, CreateSaysWhyItCannotServe) {
  const TempDir dir("create");
  ServerOptions bad = TestOptions(dir.File("map.db"));
  bad.workers = -1;
  StatusOr<std::unique_ptr<Server>> server = Server::Create(bad);
  ASSERT_FALSE(server.ok());
  EXPECT_EQ(server.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(server.status().message().find("--workers"), std::string::npos);

  ServerOptions no_models = TestOptions(dir.File("map.db"));
  no_models.recognizer.analyzer.segmentation = SegmentationMethod::kOrganization;
  no_models.recognizer.analyzer.organization.models_dir = dir.File("no_such_models");
  server = Server::Create(no_models);
  ASSERT_FALSE(server.ok());
  EXPECT_NE(server.status().message().find("placerec-train background"), std::string::npos)
      << server.status().message();

  const std::string foreign = dir.File("notes.txt");
  const std::string text(4096, 'x');
  std::ofstream(foreign) << text;
  server = Server::Create(TestOptions(foreign));
  ASSERT_FALSE(server.ok());
  EXPECT_EQ(server.status().code(), StatusCode::kIoError);
  EXPECT_NE(server.status().message().find(foreign), std::string::npos)
      << server.status().message();
  EXPECT_NE(server.status().message().find("not a SQLite database"), std::string::npos)
      << server.status().message();
  std::ifstream in(foreign);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), text);

  // A PostgreSQL map that cannot be reached: the error names the URL.
  const std::string unreachable = "postgresql:///placerec?host=" + dir.File("no_socket_here");
  server = Server::Create(TestOptions(unreachable));
  ASSERT_FALSE(server.ok());
  EXPECT_EQ(server.status().code(), StatusCode::kIoError);
  EXPECT_NE(server.status().message().find(unreachable), std::string::npos)
      << server.status().message();

  ServerOptions bad_url = TestOptions(dir.File("map.db"));
  bad_url.lcm_urls = {"nosuchprovider://x"};
  server = Server::Create(bad_url);
  ASSERT_FALSE(server.ok());
  EXPECT_EQ(server.status().code(), StatusCode::kIoError);
  EXPECT_NE(server.status().message().find("nosuchprovider://x"), std::string::npos)
      << server.status().message();
}

// Without a URL LCM reads LCM_DEFAULT_URL; the error names the variable and its value.
TEST(ServerTest, CreateNamesTheUrlTakenFromTheEnvironment) {
  const TempDir dir("environment");
  const char* previous = std::getenv("LCM_DEFAULT_URL");
  const std::string saved = previous != nullptr ? previous : "";
  ASSERT_EQ(setenv("LCM_DEFAULT_URL", "nosuchprovider://y", 1), 0);
  ServerOptions options = TestOptions(dir.File("map.db"));
  options.lcm_urls.clear();
  const StatusOr<std::unique_ptr<Server>> server = Server::Create(options);
  if (previous != nullptr) {
    setenv("LCM_DEFAULT_URL", saved.c_str(), 1);
  } else {
    unsetenv("LCM_DEFAULT_URL");
  }
  ASSERT_FALSE(server.ok());
  EXPECT_NE(server.status().message().find("LCM_DEFAULT_URL=nosuchprovider://y"), std::string::npos)
      << server.status().message();
}

// The default segmentation loads the shipped models (models/, part of the repository).
TEST(ServerTest, DefaultOptionsServeWithTheShippedModels) {
  const TempDir dir("models");
  ServerOptions options;
  options.db_path = dir.File("map.db");
  options.lcm_urls = {"memq://"};
  options.auth.enabled = false;  // the models are the point here
  const StatusOr<std::unique_ptr<Server>> server = Server::Create(options);
  ASSERT_TRUE(server.ok()) << server.status().ToString();
}

// Authentication is on by default: without a keys file the server refuses to start and says what
// to do; an unreadable keys file is named.
TEST(ServerTest, CreateRefusesToServeWithoutKeys) {
  const TempDir dir("keys");
  ServerOptions options = TestOptions(dir.File("map.db"));
  options.auth = AuthOptions();
  StatusOr<std::unique_ptr<Server>> server = Server::Create(options);
  ASSERT_FALSE(server.ok());
  EXPECT_NE(server.status().message().find("--keys"), std::string::npos)
      << server.status().message();
  EXPECT_NE(server.status().message().find("--auth off"), std::string::npos)
      << server.status().message();
  options.auth.keys_file = dir.File("missing_keys");
  server = Server::Create(options);
  ASSERT_FALSE(server.ok());
  EXPECT_NE(server.status().message().find("missing_keys"), std::string::npos)
      << server.status().message();
}

// By default a server runs one worker per core (OpenCV holds each frame to one thread, so fewer
// would leave cores idle on a larger machine); a given count is kept.
TEST(ServerOptionsTest, WorkersDefaultToOnePerCore) {
  ServerOptions options;
  EXPECT_EQ(options.workers, 0);
  // The cores this process may use: held to one (as taskset would), one worker.
  cpu_set_t all, one;
  ASSERT_EQ(sched_getaffinity(0, sizeof(all), &all), 0);
  const int cores = CPU_COUNT(&all);
  // At most those cores (fewer under a cgroup's CPU quota).
  EXPECT_GE(options.ResolvedWorkers(), 1);
  EXPECT_LE(options.ResolvedWorkers(), std::min(cores, 256));
  int first = 0;
  while (!CPU_ISSET(first, &all)) ++first;
  CPU_ZERO(&one);
  CPU_SET(first, &one);
  ASSERT_EQ(sched_setaffinity(0, sizeof(one), &one), 0);
  const int held = options.ResolvedWorkers();
  ASSERT_EQ(sched_setaffinity(0, sizeof(all), &all), 0);
  EXPECT_EQ(held, 1);
  options.workers = 3;
  EXPECT_EQ(options.ResolvedWorkers(), 3);
}

// A cgroup's CPU quota in whole cores, rounded up; no quota or unreadable text gives 0.
TEST(ServerOptionsTest, CpuQuotaInCores) {
  EXPECT_EQ(CoresOfCpuMax("max 100000"), 0);
  EXPECT_EQ(CoresOfCpuMax("200000 100000"), 2);
  EXPECT_EQ(CoresOfCpuMax("150000 100000"), 2);
  EXPECT_EQ(CoresOfCpuMax("50000 100000"), 1);
  EXPECT_EQ(CoresOfCpuMax(""), 0);
  EXPECT_EQ(CoresOfCpuMax("lots 100000"), 0);
  EXPECT_EQ(CoresOfCfsQuota("-1", "100000"), 0);
  EXPECT_EQ(CoresOfCfsQuota("400000", "100000"), 4);
  EXPECT_EQ(CoresOfCfsQuota("", ""), 0);
  EXPECT_EQ(CoresOfCpuMax("100000000 1000"), 256);  // never more workers than the limit
}

// A server opened on an existing map serves all of it; before any frame the heartbeat reports
// the map's exact counts, the pool, and nothing answered.
TEST(ServerTest, HeartbeatReportsTheMapReloadedFromItsFile) {
  const TempDir dir("reload");
  const std::string db = dir.File("map.db");
  ASSERT_NO_FATAL_FAILURE(WriteMap(db));
  ServerOptions options = TestOptions(db);
  options.workers = 3;
  options.queue_capacity = 5;
  const StatusOr<std::unique_ptr<Server>> server = Server::Create(options);
  ASSERT_TRUE(server.ok()) << server.status().ToString();
  const status_t status = (*server)->CurrentStatus();
  EXPECT_EQ(status.map_places, 2);
  EXPECT_EQ(status.map_landmarks, 3);
  EXPECT_EQ(status.map_descriptors, 30);
  EXPECT_EQ(status.map, "sqlite:" + db);
  EXPECT_FALSE(status.version.empty());
  EXPECT_GE(status.map_open_ms, 0.0);
  EXPECT_GE(status.uptime_s, 0.0);
  EXPECT_EQ(status.workers, 3);
  EXPECT_EQ(status.queue_capacity, 5);
  EXPECT_EQ(status.queue_depth, 0);
  EXPECT_EQ(status.in_progress, 0);
  EXPECT_EQ(status.robots, 0);
  EXPECT_EQ(status.frames_answered, 0);
  EXPECT_EQ(status.frames_failed, 0);
  EXPECT_EQ(status.frames_overloaded, 0);
  EXPECT_EQ(status.messages_dropped, 0);
  EXPECT_EQ(status.frames_per_second, 0.0);
}

// Issue 23 item 6: a map with 4 KB of random bytes in a page was served as if whole. Now the
// server refuses it at start-up, saying what to do; with --repair it drops the damaged places,
// keeps the damaged file beside the map and serves the rest.
TEST(ServerTest, ADamagedMapIsRefusedUnlessRepaired) {
  const TempDir dir("damaged");
  const std::string db = dir.File("map.db");
  constexpr int kPlaces = 10;
  {
    StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(db, SqliteStoreOptions());
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    std::mt19937 rng(3);
    for (int p = 0; p < kPlaces; ++p) {
      Place place{PlaceId(), "robot", p, 1000000 * p, 0, 320};
      std::vector<Landmark> landmarks = {RandomLandmark(60, &rng), RandomLandmark(60, &rng)};
      ASSERT_TRUE((*store)->AddPlace(&place, &landmarks).ok());
    }
  }
  {
    std::fstream file(db, std::ios::in | std::ios::out | std::ios::binary);
    file.seekg(0, std::ios::end);
    const int64_t pages = static_cast<int64_t>(file.tellg()) / 4096;
    ASSERT_GT(pages, 20);
    std::mt19937 random(11);
    std::string noise(4096, '\0');
    for (char& c : noise) c = static_cast<char>(random());
    file.seekp(pages / 2 * 4096);
    file.write(noise.data(), static_cast<std::streamsize>(noise.size()));
  }
  StatusOr<std::unique_ptr<Server>> refused = Server::Create(TestOptions(db));
  ASSERT_FALSE(refused.ok()) << "a damaged map was served";
  EXPECT_EQ(refused.status().code(), StatusCode::kIoError);
  EXPECT_NE(refused.status().message().find("is damaged"), std::string::npos)
      << refused.status().message();
  EXPECT_NE(refused.status().message().find("--repair"), std::string::npos)
      << refused.status().message();

  ServerOptions repair = TestOptions(db);
  repair.repair = true;
  StatusOr<std::unique_ptr<Server>> repaired = Server::Create(repair);
  ASSERT_TRUE(repaired.ok()) << repaired.status().ToString();
  const status_t status = (*repaired)->CurrentStatus();
  EXPECT_GT(status.map_places, 0);
  EXPECT_LT(status.map_places, kPlaces);
  EXPECT_EQ(status.map_landmarks, 2 * status.map_places);
  EXPECT_TRUE(std::filesystem::exists(db + ".damaged"));
}

// Run serves until Stop, from another thread or before it even started, and then returns OK.
TEST(ServerTest, RunReturnsOnceStopped) {
  const TempDir dir("run");
  for (const bool stop_first : {false, true}) {
    SCOPED_TRACE(stop_first ? "stopped before Run" : "stopped while running");
    StatusOr<std::unique_ptr<Server>> created =
        Server::Create(TestOptions(dir.File(stop_first ? "first.db" : "running.db")));
    ASSERT_TRUE(created.ok()) << created.status().ToString();
    std::unique_ptr<Server> server = std::move(*created);
    Server* s = server.get();
    if (stop_first) s->Stop();
    auto returned = std::make_shared<std::promise<Status>>();
    std::future<Status> run = returned->get_future();
    std::thread([s, returned] { returned->set_value(s->Run()); }).detach();
    s->Stop();
    // Run returns within about 0.1 s; the bound only turns a hang into a failure.
    if (run.wait_for(std::chrono::seconds(30)) != std::future_status::ready) {
      server.release();  // Run still uses it: leaked rather than destroyed under it
      FAIL() << "Run did not return within 30 s of Stop";
    }
    const Status result = run.get();
    EXPECT_TRUE(result.ok()) << result.ToString();
    EXPECT_EQ(s->CurrentStatus().frames_answered, 0);
  }
}

// Issue 24 item 2: a clean stop writes the descriptor index snapshot beside the map, and the
// next open loads the tree from it instead of growing it again.
TEST(ServerTest, ACleanStopWritesTheIndexSnapshot) {
  const TempDir dir("snapshot");
  const std::string db = dir.File("map.db");
  ASSERT_NO_FATAL_FAILURE(WriteMap(db));
  {
    StatusOr<std::unique_ptr<Server>> created = Server::Create(TestOptions(db));
    ASSERT_TRUE(created.ok()) << created.status().ToString();
    std::unique_ptr<Server> server = std::move(*created);
    Server* s = server.get();
    auto returned = std::make_shared<std::promise<Status>>();
    std::future<Status> run = returned->get_future();
    std::thread([s, returned] { returned->set_value(s->Run()); }).detach();
    s->Stop();
    if (run.wait_for(std::chrono::seconds(30)) != std::future_status::ready) {
      server.release();
      FAIL() << "Run did not return within 30 s of Stop";
    }
    EXPECT_TRUE(run.get().ok());
  }
  ASSERT_TRUE(std::filesystem::exists(db + ".index"));
  StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(db, SqliteStoreOptions());
  ASSERT_TRUE(store.ok());
  StatusOr<std::unique_ptr<PlaceMap>> map =
      PlaceMap::Open(std::move(*store), TestOptions(db).recognizer.index);
  ASSERT_TRUE(map.ok());
  EXPECT_TRUE((*map)->snapshot_load().used) << (*map)->snapshot_load().message;
  EXPECT_EQ((*map)->snapshot_load().inserted_points, 0);
}

}  // namespace
}  // namespace placerec
