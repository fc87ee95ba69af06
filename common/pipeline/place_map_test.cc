#include "common/pipeline/place_map.h"

#include <chrono>
#include <future>
#include <memory>
#include <mutex>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "common/recognition/recognition_test_util.h"
#include "common/storage/sqlite_store.h"

namespace placerec {
namespace {

// A store whose AddPlace waits until the test lets it go on: a slow commit (fsync on a busy disk,
// a remote database) made visible.
class HeldStore : public LandmarkStore {
 public:
  explicit HeldStore(std::unique_ptr<LandmarkStore> inner) : inner_(std::move(inner)) {}

  Status AddPlace(Place* place, std::vector<Landmark>* landmarks) override {
    entered_.set_value();
    release_.get_future().wait();
    return inner_->AddPlace(place, landmarks);
  }
  Status LoadPlaces(const std::function<void(const Place&)>& visit) const override {
    return inner_->LoadPlaces(visit);
  }
  Status LoadLandmarks(const std::function<void(Landmark&&)>& visit) const override {
    return inner_->LoadLandmarks(visit);
  }
  StatusOr<StoreCounts> Counts() const override { return inner_->Counts(); }
  StatusOr<uint64_t> Checksum() const override { return inner_->Checksum(); }
  std::string Describe() const override { return inner_->Describe(); }

  std::future<void> Entered() { return entered_.get_future(); }
  void Release() {
    std::call_once(released_, [this] { release_.set_value(); });
  }

 private:
  std::unique_ptr<LandmarkStore> inner_;
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

}  // namespace
}  // namespace placerec
