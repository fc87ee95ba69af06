// Tests of the seed's loop decision (seed_decision.h; seed §5.7 steps 5-6): scene sets, the
// matched fraction, close landmark counts and the recent-past filter.
#include "common/recognition/seed_decision.h"

#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace placerec {
namespace {

TEST(SeedDecisionTest, OptionsAreChecked) {
  std::string error;
  EXPECT_TRUE(SeedLoopOptions().Check(&error)) << error;
  SeedLoopOptions bad;
  bad.min_matched_fraction = 0;
  EXPECT_FALSE(bad.Check(&error));
  bad = SeedLoopOptions();
  bad.min_count_ratio = 1.5;
  EXPECT_FALSE(bad.Check(&error));
}

// "around 50% of LO_c get matched with LO_m" and "|LO_c| is close to |LO_m|".
TEST(SeedDecisionTest, HalfTheLandmarksAndCloseCounts) {
  const SeedLoopOptions options;  // 0.5 and 0.5
  EXPECT_TRUE(SeedLoopClosure(2, 4, 4, options));
  EXPECT_FALSE(SeedLoopClosure(1, 4, 4, options));  // a quarter
  EXPECT_TRUE(SeedLoopClosure(2, 4, 8, options));   // 4 of 8: close enough
  EXPECT_FALSE(SeedLoopClosure(2, 4, 9, options));  // not close
  EXPECT_FALSE(SeedLoopClosure(0, 0, 0, options));
}

// A stored object brings every scene of its set; a place seen by more of the frame's landmarks
// ranks first; places the recent-past rule forbids are left out.
TEST(SeedDecisionTest, ScenesOfMatchedObjectsAreRanked) {
  std::map<PlaceId, Place> places;
  for (int id = 1; id <= 3; ++id) {
    Place place;
    place.id = PlaceId(id);
    place.robot = id == 3 ? "self" : "other";
    place.sequence = id;
    place.num_landmarks = 2;
    places[place.id] = place;
  }
  places[PlaceId(2)].seen_landmarks = {LandmarkId(10)};  // place 2 saw landmark 10 again
  // Landmark 10 was stored at place 1, 11 at place 2, 12 at place 3.
  const std::map<LandmarkId, std::vector<PlaceId>> scenes = {
      {LandmarkId(10), {PlaceId(1), PlaceId(2)}},
      {LandmarkId(11), {PlaceId(2)}},
      {LandmarkId(12), {PlaceId(3)}}};
  std::vector<LandmarkMatch> objects(3);
  objects[0].query_object = 0;
  objects[0].landmark = LandmarkId(10);
  objects[1].query_object = 1;
  objects[1].landmark = LandmarkId(11);
  objects[2].query_object = 2;
  objects[2].landmark = LandmarkId(12);
  bool loop = false;
  const std::vector<PlaceMatch> ranked = SeedRankPlaces(
      objects, 3, [&](LandmarkId id) { return scenes.at(id); },
      [&](PlaceId id) -> const Place* { return &places.at(id); },
      [](const Place& place) { return place.robot != "self"; }, SeedLoopOptions(), 10, &loop);
  ASSERT_EQ(ranked.size(), 2u);  // place 3 is the robot's own recent past
  EXPECT_EQ(ranked[0].place.id, PlaceId(2));
  EXPECT_EQ(ranked[0].matched_landmarks, 2);
  EXPECT_EQ(ranked[0].score, 2.0);  // 3 landmarks against 2 + 1: close
  EXPECT_EQ(ranked[1].place.id, PlaceId(1));
  EXPECT_EQ(ranked[1].matched_landmarks, 1);
  EXPECT_TRUE(loop);  // 2 of 3 matched

  // With only landmark 10 matched, 1 of 3 is not about half: no loop.
  objects.resize(1);
  SeedRankPlaces(
      objects, 3, [&](LandmarkId id) { return scenes.at(id); },
      [&](PlaceId id) -> const Place* { return &places.at(id); }, [](const Place&) { return true; },
      SeedLoopOptions(), 10, &loop);
  EXPECT_FALSE(loop);
}

}  // namespace
}  // namespace placerec
