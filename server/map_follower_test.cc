// The map follower against a real throw-away PostgreSQL cluster (scripts/pg.sh): it indexes the
// places another writer commits (those before it started too), catches up after the database was
// stopped and started again, and an Insert through a map indexed by its follower returns with its
// place indexed, falling back to indexing it itself when the follower does not bring it back.
// Skips only when the PostgreSQL binaries are missing.
#include "server/map_follower.h"

#include <gtest/gtest.h>

#include <chrono>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "common/pipeline/place_map.h"
#include "common/storage/postgres_store.h"
#include "common/storage/postgres_testing.h"
#include "common/storage/storage_testing.h"

namespace placerec {
namespace {

using testing_postgres::TestCluster;
using testing_storage::ExplicitLandmark;
using Clock = std::chrono::steady_clock;

Place MakePlace(const std::string& robot, int64_t sequence) {
  Place place;
  place.robot = robot;
  place.sequence = sequence;
  place.utime = 1700000000000000 + sequence * 100000;
  place.image_width = 640;
  return place;
}

// Inserts place (robot, sequence) with two landmarks through `store`.
void Insert(LandmarkStore* store, const std::string& robot, int64_t sequence) {
  Place place = MakePlace(robot, sequence);
  std::vector<Landmark> landmarks = {ExplicitLandmark(0), ExplicitLandmark(1)};
  const Status status = store->AddPlace(&place, &landmarks);
  ASSERT_TRUE(status.ok()) << status.ToString();
}

// Waits up to `seconds` for `map` to hold `places` places.
bool WaitForPlaces(const PlaceMap& map, int64_t places, double seconds) {
  const auto deadline = Clock::now() + std::chrono::duration<double>(seconds);
  while (Clock::now() < deadline) {
    if (map.Counts().places == places) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return map.Counts().places == places;
}

class MapFollowerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    StatusOr<std::unique_ptr<TestCluster>> cluster =
        TestCluster::Start(std::string(PLACEREC_SOURCE_DIR) + "/scripts/pg.sh");
    if (!cluster.ok() && cluster.status().code() == StatusCode::kNotFound) {
      GTEST_SKIP() << cluster.status().message();
    }
    ASSERT_TRUE(cluster.ok()) << cluster.status().ToString();
    cluster_ = std::move(*cluster);
    StatusOr<std::unique_ptr<LandmarkStore>> writer = OpenPostgresStore(cluster_->Url(), {});
    ASSERT_TRUE(writer.ok()) << writer.status().ToString();
    writer_ = std::move(*writer);
    StatusOr<std::unique_ptr<LandmarkStore>> own = OpenPostgresStore(cluster_->Url(), {});
    ASSERT_TRUE(own.ok()) << own.status().ToString();
    // One place before the map opens, so that the map loads it.
    Insert(writer_.get(), "other", 0);
    StatusOr<std::unique_ptr<PlaceMap>> map = PlaceMap::Open(std::move(*own), {});
    ASSERT_TRUE(map.ok()) << map.status().ToString();
    map_ = std::move(*map);
  }

  // A follower of the map from its loaded places on; `added` collects what it adds.
  std::unique_ptr<MapFollower> Follow() {
    PlaceId last;
    map_->ForEachPlace([&last](const Place& place) {
      if (last < place.id) last = place.id;
    });
    return std::make_unique<MapFollower>(cluster_->Url(), PostgresStoreOptions(),
                                         MapFollowerOptions(), map_.get(), last,
                                         [this](const Place& place) {
                                           std::lock_guard lock(mutex_);
                                           added_.push_back(place);
                                         });
  }

  std::unique_ptr<TestCluster> cluster_;
  std::unique_ptr<LandmarkStore> writer_;
  std::unique_ptr<PlaceMap> map_;
  std::mutex mutex_;
  std::vector<Place> added_;
};

TEST(MapFollowerOptionsTest, DefaultsPassAndBadValuesFail) {
  std::string error;
  EXPECT_TRUE(MapFollowerOptions().Check(&error)) << error;
  MapFollowerOptions bad;
  bad.retry_s = 0;
  EXPECT_FALSE(bad.Check(&error));
  bad = MapFollowerOptions();
  bad.batch_places = 0;
  EXPECT_FALSE(bad.Check(&error));
}

TEST_F(MapFollowerTest, FollowsAnotherWriterAndCatchesUpAfterAnOutage) {
  ASSERT_EQ(map_->Counts().places, 1);
  // Committed after the map loaded, before the follower started: caught up at its start.
  Insert(writer_.get(), "other", 1);
  std::unique_ptr<MapFollower> follower = Follow();
  follower->Start();
  ASSERT_TRUE(WaitForPlaces(*map_, 2, 1.0));
  for (int i = 2; i < 5; ++i) Insert(writer_.get(), "other", i);
  ASSERT_TRUE(WaitForPlaces(*map_, 5, 1.0)) << map_->Counts().places;
  EXPECT_EQ(map_->Counts().landmarks, 10);
  EXPECT_TRUE(follower->connected());

  // The database goes away and comes back; the next place arrives through the reconnected
  // follower (it retries every 0.5 s).
  ASSERT_TRUE(cluster_->Down());
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ASSERT_TRUE(cluster_->Up());
  Insert(writer_.get(), "other", 5);
  EXPECT_TRUE(WaitForPlaces(*map_, 6, 3.0)) << map_->Counts().places;
  follower->Stop();
  EXPECT_EQ(follower->places_added(), 5);
  std::lock_guard lock(mutex_);
  ASSERT_EQ(added_.size(), 5u);
  for (size_t i = 0; i < added_.size(); ++i) {
    EXPECT_EQ(added_[i].robot, "other");
    EXPECT_EQ(added_[i].sequence, static_cast<int64_t>(i + 1));
    EXPECT_EQ(added_[i].num_landmarks, 2);
  }
}

// A place whose rows do not read back whole (one with a damaged landmark, one with a damaged
// place row) held back every later place: the follower retried the same read every 0.5 s for
// good. Now the damaged places are left out (logged) and the later ones are followed.
TEST_F(MapFollowerTest, ADamagedPlaceIsLeftOutAndTheLaterOnesAreFollowed) {
  for (int i = 1; i < 4; ++i) Insert(writer_.get(), "other", i);
  const std::string place_of = "(SELECT id FROM places WHERE robot = 'other' AND sequence = ";
  ASSERT_TRUE(testing_postgres::ExecPg(cluster_->Url(),
                                       "UPDATE landmarks SET keypoints = '\\x0001'::bytea "
                                       "WHERE place_id = " +
                                           place_of + "1)")
                  .ok());
  ASSERT_TRUE(
      testing_postgres::ExecPg(cluster_->Url(),
                               "UPDATE places SET image_width = -1 WHERE id = " + place_of + "2)")
          .ok());
  std::unique_ptr<MapFollower> follower = Follow();
  follower->Start();
  EXPECT_TRUE(WaitForPlaces(*map_, 2, 2.0)) << map_->Counts().places;
  Insert(writer_.get(), "other", 4);
  EXPECT_TRUE(WaitForPlaces(*map_, 3, 2.0)) << map_->Counts().places;
  follower->Stop();
  EXPECT_EQ(follower->places_added(), 2);
  EXPECT_EQ(follower->places_damaged(), 2);
  EXPECT_EQ(map_->Counts().landmarks, 2 + 2 + 2);
  std::lock_guard lock(mutex_);
  ASSERT_EQ(added_.size(), 2u);
  EXPECT_EQ(added_[0].sequence, 3);
  EXPECT_EQ(added_[1].sequence, 4);
}

TEST_F(MapFollowerTest, AnInsertReturnsWithItsPlaceIndexedThroughTheFollower) {
  map_->IndexThroughFollower(std::chrono::milliseconds(2000));
  std::unique_ptr<MapFollower> follower = Follow();
  follower->Start();
  Insert(writer_.get(), "other", 1);
  Place mine = MakePlace("mine", 0);
  std::vector<Landmark> landmarks = {ExplicitLandmark(2)};
  const auto start = Clock::now();
  ASSERT_TRUE(map_->Insert(&mine, &landmarks).ok());
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - start).count(), 1.0);
  // Both places are indexed when Insert returns: the other writer's (lower id) and this one.
  EXPECT_EQ(map_->Counts().places, 3);
  EXPECT_EQ(map_->Counts().landmarks, 2 + 2 + 1);
  {
    // The follower reports a place after indexing it, so Insert may return (its place indexed)
    // just before the report of it arrives.
    const auto deadline = Clock::now() + std::chrono::seconds(1);
    std::unique_lock lock(mutex_);
    while (added_.size() < 2 && Clock::now() < deadline) {
      lock.unlock();
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
      lock.lock();
    }
    ASSERT_EQ(added_.size(), 2u);  // the follower added both, in id order
    EXPECT_EQ(added_[0].robot, "other");
    EXPECT_EQ(added_[1].robot, "mine");
    EXPECT_EQ(added_[1].id, mine.id);
  }

  // Without a follower the place is indexed by Insert itself after the wait.
  follower->Stop();
  map_->IndexThroughFollower(std::chrono::milliseconds(100));
  Place alone = MakePlace("mine", 1);
  std::vector<Landmark> more = {ExplicitLandmark(3)};
  ASSERT_TRUE(map_->Insert(&alone, &more).ok());
  EXPECT_EQ(map_->Counts().places, 4);
  EXPECT_EQ(map_->Counts().landmarks, 6);
}

}  // namespace
}  // namespace placerec
