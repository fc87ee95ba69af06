// Tests of the landmark index (landmark_index.h; seed §5.6): retrieval of stored objects through
// the texture range and the colour filter, object-level and place-level matches, with both
// searches.
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "common/recognition/landmark_index.h"
#include "common/recognition/recognition_test_util.h"

namespace placerec {
namespace {

using recognition_test::MakeLandmark;
using recognition_test::Noisy;
using recognition_test::RandomDescriptors;

class LandmarkIndexTest : public ::testing::TestWithParam<IndexSearch> {};

TEST_P(LandmarkIndexTest, RetrievesTheRightLandmarkAndRespectsFilters) {
  std::mt19937 rng(5);
  LandmarkIndexOptions options;
  options.search = GetParam();
  LandmarkIndex index(options);
  std::vector<cv::Mat> stored;
  for (int p = 0; p < 10; ++p) index.AddPlace({PlaceId(p), "robot", p * 100, 0, 4});
  for (int i = 0; i < 40; ++i) {
    stored.push_back(RandomDescriptors(30, &rng));
    index.Add(MakeLandmark(i, i / 4, stored.back(), 30, {0.1f}));
  }
  EXPECT_EQ(index.num_landmarks(), 40u);
  EXPECT_EQ(index.num_descriptors(), 1200u);

  IndexQuery query;
  query.sift_count = 30;
  query.colour.peaks = {0.15f};
  query.descriptors = Noisy(stored[13].rowRange(0, 20), &rng);
  auto all_places = [](PlaceId) { return true; };
  IndexResult found = index.Query({query}, all_places);
  ASSERT_EQ(found.objects.size(), 1u);
  EXPECT_EQ(found.objects[0].landmark, LandmarkId(13));
  EXPECT_EQ(found.objects[0].place, PlaceId(3));
  EXPECT_EQ(found.objects[0].matches.size(), 20u);
  EXPECT_EQ(index.Candidates(query).size(), 40u);
  // The place's descriptors match at place level too: every query row, to landmark 13's rows.
  ASSERT_EQ(found.place_points.size(), 1u);
  ASSERT_EQ(found.place_points.at(PlaceId(3)).size(), 20u);
  for (const PointMatch& p : found.place_points.at(PlaceId(3))) {
    EXPECT_EQ(index.landmark(p.slot).id, LandmarkId(13));
    EXPECT_EQ(p.train, p.query_row);
  }

  // The place filter removes it.
  EXPECT_TRUE(index.Query({query}, [](PlaceId p) { return p != PlaceId(3); }).objects.empty());

  // Out of the texture range: 30 keypoints are outside [2n/3, 4n/3] for n = 60.
  IndexQuery far = query;
  far.sift_count = 60;
  EXPECT_TRUE(index.Candidates(far).empty());
  EXPECT_TRUE(index.Query({far}, all_places).objects.empty());

  // Another colour.
  IndexQuery blue = query;
  blue.colour.peaks = {-2.0f};
  EXPECT_TRUE(index.Query({blue}, all_places).objects.empty());

  // Fewer than 7 matching descriptors is not a match.
  IndexQuery few = query;
  few.descriptors = Noisy(stored[13].rowRange(0, 6), &rng);
  EXPECT_TRUE(index.Query({few}, all_places).objects.empty());
}

INSTANTIATE_TEST_SUITE_P(Searches, LandmarkIndexTest,
                         ::testing::Values(IndexSearch::kFlann, IndexSearch::kExhaustive));

}  // namespace
}  // namespace placerec
