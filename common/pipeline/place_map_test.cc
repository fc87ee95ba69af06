#include "common/pipeline/place_map.h"

#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <future>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <sqlite3.h>

#include "common/recognition/recognition_test_util.h"
#include "common/storage/forwarding_store_testing.h"
#include "common/storage/sqlite_store.h"

namespace placerec {
namespace {

// A store whose AddPlace waits until the test lets it go on: a slow commit (fsync on a busy disk,
// a remote database) made visible.
class HeldStore : public testing_storage::ForwardingStore {
 public:
  using ForwardingStore::ForwardingStore;

  Status AddPlace(Place* place, std::vector<Landmark>* landmarks) override {
    entered_.set_value();
    release_.get_future().wait();
    return ForwardingStore::AddPlace(place, landmarks);
  }

  std::future<void> Entered() { return entered_.get_future(); }
  void Release() {
    std::call_once(released_, [this] { release_.set_value(); });
  }

 private:
  std::promise<void> entered_;
  std::promise<void> release_;
  std::once_flag released_;
};

// Lets a held commit go on when the test leaves, also by a failed assertion (the insert's
// future waits for it).
struct ReleaseAtExit {
  HeldStore* store;
  ~ReleaseAtExit() { store->Release(); }
};

Landmark TestLandmark(int seed) {
  Landmark landmark;
  std::mt19937 rng(seed);
  landmark.descriptors = recognition_test::RandomDescriptors(20, &rng);
  for (int r = 0; r < landmark.descriptors.rows; ++r) {
    landmark.keypoints.emplace_back(cv::Point2f(10.0f * r, 5.0f * r), 4.0f);
  }
  landmark.sift_count = landmark.descriptors.rows;
  landmark.colour.peaks = {0.5f};
  landmark.box = cv::Rect(0, 0, 50, 50);
  return landmark;
}

TEST(PlaceMapTest, LookupsGoOnWhileAnInsertCommits) {
  StatusOr<std::unique_ptr<LandmarkStore>> inner =
      OpenSqliteStore(":memory:", SqliteStoreOptions());
  ASSERT_TRUE(inner.ok());
  auto held = std::make_unique<HeldStore>(std::move(*inner));
  HeldStore* store = held.get();
  std::future<void> entered = store->Entered();
  StatusOr<std::unique_ptr<PlaceMap>> opened =
      PlaceMap::Open(std::move(held), LandmarkIndexOptions());
  ASSERT_TRUE(opened.ok());
  PlaceMap& map = **opened;

  std::future<Status> inserted = std::async(std::launch::async, [&map] {
    Place place;
    place.robot = "r1";
    place.sequence = 1;
    std::vector<Landmark> landmarks = {TestLandmark(1)};
    return map.Insert(&place, &landmarks);
  });
  const ReleaseAtExit release_at_exit{store};
  ASSERT_EQ(entered.wait_for(std::chrono::seconds(10)), std::future_status::ready);

  // The commit is held: a lookup (and the counts) must still answer.
  std::future<int64_t> looked_up = std::async(std::launch::async, [&map] {
    MapLookup lookup;
    lookup.recent.robot = "r2";
    lookup.image_width = 640;
    const Landmark query = TestLandmark(1);
    lookup.objects.push_back({query.sift_count, query.colour, query.descriptors});
    lookup.object_keypoints.push_back(query.keypoints);
    map.Lookup(lookup, LoopDecisionOptions());
    return map.Counts().places;
  });
  const bool answered = looked_up.wait_for(std::chrono::seconds(5)) == std::future_status::ready;
  store->Release();
  EXPECT_TRUE(answered) << "a lookup waited for another robot's commit";
  EXPECT_EQ(looked_up.get(), 0);  // the place is not indexed before its commit returns
  ASSERT_TRUE(inserted.get().ok());
  EXPECT_EQ(map.Counts().places, 1);
}

// A map file in a fresh temporary directory, removed with its snapshot at the end.
class MapFile {
 public:
  MapFile() {
    std::string pattern = ::testing::TempDir() + "placerec_place_map_XXXXXX";
    CHECK(mkdtemp(pattern.data()) != nullptr);
    dir_ = pattern;
  }
  ~MapFile() { std::filesystem::remove_all(dir_); }
  std::string path() const { return dir_ + "/map.db"; }

 private:
  std::string dir_;
};

std::unique_ptr<PlaceMap> OpenMap(const std::string& path, const LandmarkIndexOptions& options) {
  StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(path, SqliteStoreOptions());
  CHECK(store.ok()) << store.status().message();
  StatusOr<std::unique_ptr<PlaceMap>> map = PlaceMap::Open(std::move(*store), options);
  CHECK(map.ok()) << map.status().message();
  return std::move(*map);
}

// Place p of robot r1 sees landmarks of seeds p, p + 1, p + 2 (each seen again by the next two
// places, with noise), ten seconds after place p - 1.
void InsertPlace(int p, PlaceMap* map) {
  Place place;
  place.robot = "r1";
  place.sequence = p;
  place.utime = 10000000LL * p;
  place.image_width = 640;
  std::vector<Landmark> landmarks;
  std::mt19937 rng(1000 + p);
  for (int seed = p; seed < p + 3; ++seed) {
    Landmark landmark = TestLandmark(seed);
    landmark.descriptors = recognition_test::Noisy(landmark.descriptors, &rng, 10);
    landmarks.push_back(landmark);
  }
  ASSERT_TRUE(map->Insert(&place, &landmarks).ok());
}

// What the map answers: the descriptor index's neighbours of noisy copies of every test
// landmark, and the places a lookup of each ranks, with scores.
std::string Answers(const PlaceMap& map, int seeds) {
  std::ostringstream text;
  std::mt19937 rng(77);
  for (int seed = 0; seed < seeds; ++seed) {
    const Landmark query = TestLandmark(seed);
    const cv::Mat noisy = recognition_test::Noisy(query.descriptors, &rng, 25);
    std::vector<std::vector<DescriptorIndex::Neighbour>> neighbours;
    map.index().descriptor_index().Search(noisy, 2, &neighbours);
    for (const auto& list : neighbours) {
      for (const auto& n : list) text << n.owner << ":" << n.row << ":" << n.distance << " ";
    }
    MapLookup lookup;
    lookup.recent.robot = "r2";
    lookup.image_width = 640;
    lookup.objects.push_back({query.sift_count, query.colour, noisy});
    lookup.object_keypoints.push_back(query.keypoints);
    for (const PlaceMatch& match : map.Lookup(lookup, LoopDecisionOptions()).places) {
      text << "| " << match.place.id.value() << " " << match.score;
    }
    text << "\n";
  }
  return text.str();
}

// A map file of three places, then `sql` run on it behind the map's back (a damaged or old map).
void WriteThreePlacesThenDamage(const std::string& path, const char* sql) {
  {
    std::unique_ptr<PlaceMap> map = OpenMap(path, LandmarkIndexOptions());
    for (int p = 0; p < 3; ++p) InsertPlace(p, map.get());
  }
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, sql, nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);
}

TEST(PlaceMapTest, DamagedLandmarkCountsDoNotStopTheMapFromOpening) {
  MapFile file;
  WriteThreePlacesThenDamage(file.path(), "UPDATE places SET num_landmarks = 2147483647");
  StatusOr<std::unique_ptr<LandmarkStore>> store =
      OpenSqliteStore(file.path(), SqliteStoreOptions());
  ASSERT_TRUE(store.ok()) << store.status().message();
  StatusOr<std::unique_ptr<PlaceMap>> map = PlaceMap::Open(std::move(*store), {});
  ASSERT_TRUE(map.ok()) << map.status().message();
  EXPECT_EQ((*map)->Counts().landmarks, 9);
}

TEST(PlaceMapTest, CaptureTimesOutOfRangeInAnOldMapAreBoundedInMemoryAndLeftInTheFile) {
  // Before capture times were checked at intake a map could store any time; the differences
  // the map takes between them (vote windows, a robot's recent past) would overflow.
  MapFile file;
  WriteThreePlacesThenDamage(file.path(),
                             "UPDATE places SET utime = -9223372036854775807 - 1 WHERE id = 1; "
                             "UPDATE places SET utime = 9223372036854775807 WHERE id = 2");
  StatusOr<std::unique_ptr<LandmarkStore>> store =
      OpenSqliteStore(file.path(), SqliteStoreOptions());
  ASSERT_TRUE(store.ok()) << store.status().message();
  StatusOr<std::unique_ptr<PlaceMap>> map = PlaceMap::Open(std::move(*store), {});
  ASSERT_TRUE(map.ok()) << map.status().message();
  std::map<int64_t, int64_t> times;
  (*map)->ForEachPlace([&times](const Place& place) { times[place.id.value()] = place.utime; });
  ASSERT_EQ(times.size(), 3u);
  EXPECT_EQ(times[1], 0);
  EXPECT_EQ(times[2], kMaxUtime);
  // The file keeps what it held: nothing is rewritten behind the operator's back.
  StatusOr<std::unique_ptr<LandmarkStore>> again =
      OpenSqliteStore(file.path(), SqliteStoreOptions());
  ASSERT_TRUE(again.ok());
  std::map<int64_t, int64_t> stored;
  ASSERT_TRUE(
      (*again)
          ->LoadPlaces([&stored](const Place& place) { stored[place.id.value()] = place.utime; })
          .ok());
  EXPECT_EQ(stored[1], std::numeric_limits<int64_t>::min());
  EXPECT_EQ(stored[2], std::numeric_limits<int64_t>::max());
  // A place another server committed (the PostgreSQL follower's path) is bounded the same way.
  Place late;
  late.id = PlaceId(100);
  late.robot = "old-server";
  late.utime = std::numeric_limits<int64_t>::max();
  ASSERT_TRUE((*map)->AddCommitted(late, {}));
  times.clear();
  (*map)->ForEachPlace([&times](const Place& place) { times[place.id.value()] = place.utime; });
  EXPECT_EQ(times[100], kMaxUtime);
}

TEST(PlaceMapTest, ReopensFromItsIndexSnapshotWithTheSameAnswers) {
  MapFile file;
  LandmarkIndexOptions options;
  options.flann.checks = 4;  // far from exact: the answers show the shape of the tree
  std::string grown;
  {
    std::unique_ptr<PlaceMap> map = OpenMap(file.path(), options);
    EXPECT_FALSE(map->snapshot_load().used);
    for (int p = 0; p < 8; ++p) InsertPlace(p, map.get());
    bool written = false;
    ASSERT_TRUE(map->SaveIndexSnapshot(&written).ok());
    EXPECT_TRUE(written);
    EXPECT_TRUE(std::ifstream(file.path() + ".index").good());
    // Places committed after the snapshot, as by a server killed before its next one.
    for (int p = 8; p < 14; ++p) InsertPlace(p, map.get());
    grown = Answers(*map, 16);
    ASSERT_NE(grown.find("| "), std::string::npos) << "no lookup found a place: a weak test";
  }
  {
    std::unique_ptr<PlaceMap> map = OpenMap(file.path(), options);
    EXPECT_TRUE(map->snapshot_load().used) << map->snapshot_load().message;
    EXPECT_EQ(map->snapshot_load().covered_adds, 8 * 3);
    EXPECT_EQ(map->snapshot_load().inserted_points, 6 * 3 * 20);
    EXPECT_EQ(Answers(*map, 16), grown);
    bool written = false;
    ASSERT_TRUE(map->SaveIndexSnapshot(&written).ok());
    EXPECT_TRUE(written);
  }
  {
    std::unique_ptr<PlaceMap> map = OpenMap(file.path(), options);
    EXPECT_TRUE(map->snapshot_load().used) << map->snapshot_load().message;
    EXPECT_EQ(map->snapshot_load().inserted_points, 0);
    EXPECT_EQ(Answers(*map, 16), grown);
    // Up to date: nothing to write.
    bool written = true;
    ASSERT_TRUE(map->SaveIndexSnapshot(&written).ok());
    EXPECT_FALSE(written);
  }
  // The same map without any snapshot answers alike too.
  ASSERT_EQ(std::remove((file.path() + ".index").c_str()), 0);
  std::unique_ptr<PlaceMap> map = OpenMap(file.path(), options);
  EXPECT_FALSE(map->snapshot_load().used);
  EXPECT_EQ(Answers(*map, 16), grown);
}

TEST(PlaceMapTest, SnapshotOfAnotherMapIsIgnored) {
  MapFile first;
  MapFile second;
  LandmarkIndexOptions options;
  options.flann.checks = 4;
  std::string expected;
  {
    std::unique_ptr<PlaceMap> map = OpenMap(first.path(), options);
    for (int p = 0; p < 6; ++p) InsertPlace(p, map.get());
    ASSERT_TRUE(map->SaveIndexSnapshot().ok());
  }
  {
    std::unique_ptr<PlaceMap> map = OpenMap(second.path(), options);
    for (int p = 3; p < 9; ++p) InsertPlace(p, map.get());
    expected = Answers(*map, 12);
  }
  std::ifstream in(first.path() + ".index", std::ios::binary);
  std::ofstream(second.path() + ".index", std::ios::binary) << in.rdbuf();
  std::unique_ptr<PlaceMap> map = OpenMap(second.path(), options);
  EXPECT_FALSE(map->snapshot_load().used);
  EXPECT_NE(map->snapshot_load().message.find("not the ones it covers"), std::string::npos)
      << map->snapshot_load().message;
  EXPECT_EQ(Answers(*map, 12), expected);
}

TEST(PlaceMapTest, MapsWithoutAFileKeepNoSnapshot) {
  StatusOr<std::unique_ptr<LandmarkStore>> store =
      OpenSqliteStore(":memory:", SqliteStoreOptions());
  ASSERT_TRUE(store.ok());
  StatusOr<std::unique_ptr<PlaceMap>> map =
      PlaceMap::Open(std::move(*store), LandmarkIndexOptions());
  ASSERT_TRUE(map.ok());
  InsertPlace(0, map->get());
  bool written = true;
  EXPECT_TRUE((*map)->SaveIndexSnapshot(&written).ok());
  EXPECT_FALSE(written);
}

}  // namespace
}  // namespace placerec
