// Tests of the loop decision (loop_decision.h; seed §5.7 step 6): candidate places ranked by
// geometric inliers, the orientation filter, the per-landmark inlier cap and localization among
// the best place's neighbours.
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "common/recognition/landmark_index.h"
#include "common/recognition/loop_decision.h"
#include "common/recognition/recognition_test_util.h"

namespace placerec {
namespace {

using recognition_test::MakeLandmark;
using recognition_test::RandomDescriptors;

TEST(LoopDecisionTest, DefaultsPassAndBadValuesFail) {
  LoopDecisionOptions options;
  std::string error;
  EXPECT_TRUE(LoopDecisionOptions().Check(&error)) << error;
  options.ransac_threshold = 0;
  EXPECT_FALSE(options.Check(&error));
}

TEST(LoopDecisionTest, GeometricallyConsistentPlaceRanksFirst) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> coord(0.0f, 600.0f);
  LandmarkIndex index{LandmarkIndexOptions()};
  // Place 0: a landmark whose keypoints are the query's shifted by (15, 0) (a camera moving
  // sideways); place 1: a landmark whose keypoints are scattered at random.
  const int n = 40;
  std::vector<cv::KeyPoint> query_points;
  for (int i = 0; i < n; ++i)
    query_points.emplace_back(cv::Point2f(coord(rng), coord(rng) * 0.6f), 3.0f);
  Landmark consistent = MakeLandmark(0, 0, RandomDescriptors(n, &rng), n);
  Landmark scattered = MakeLandmark(1, 1, RandomDescriptors(n, &rng), n);
  index.AddPlace({PlaceId(0), "a", 0, 0, 1});
  index.AddPlace({PlaceId(1), "a", 1, 0, 1});
  for (int i = 0; i < n; ++i) {
    consistent.keypoints[i].pt = query_points[i].pt + cv::Point2f(15.0f, 0.0f);
    scattered.keypoints[i].pt = cv::Point2f(coord(rng), coord(rng));
  }
  index.Add(consistent);
  index.Add(scattered);
  IndexResult found;
  for (int p = 0; p < 2; ++p) {
    LandmarkMatch match;
    match.query_object = 0;
    match.landmark = LandmarkId(p);
    match.place = PlaceId(p);
    for (int i = 0; i < n; ++i) {
      match.matches.push_back({i, i, 0});
      found.place_points[PlaceId(p)].push_back({0, i, p, i, 0.0f});
    }
    found.objects.push_back(match);
  }
  const Place places[2] = {{PlaceId(0), "a", 0, 0, 1}, {PlaceId(1), "a", 1, 0, 1}};
  const std::vector<PlaceMatch> ranked = RankPlaces(
      found, {query_points}, 0, index, [&places](PlaceId id) { return &places[id.value()]; },
      LoopDecisionOptions());
  ASSERT_EQ(ranked.size(), 2u);
  EXPECT_EQ(ranked[0].place.id, PlaceId(0));
  EXPECT_GE(ranked[0].inliers, 38);
  EXPECT_LT(ranked[1].inliers, ranked[0].inliers / 2);
  EXPECT_EQ(ranked[0].matched_landmarks, 1);
  EXPECT_EQ(ranked[0].matched_descriptors, n);
}

// A place whose landmark `id` has keypoints related to `query` by a sideways shift, with
// keypoint sizes scaled by `scale` and angles rotated by `rotation` degrees.
Landmark ShiftedLandmark(int64_t id, int64_t place, const std::vector<cv::KeyPoint>& query,
                         std::mt19937* rng, float scale = 1.0f, float rotation = 0.0f) {
  Landmark landmark =
      MakeLandmark(id, place, RandomDescriptors(static_cast<int>(query.size()), rng),
                   static_cast<int>(query.size()));
  for (size_t i = 0; i < query.size(); ++i) {
    landmark.keypoints[i] = query[i];
    landmark.keypoints[i].pt += cv::Point2f(15.0f, 0.0f);
    landmark.keypoints[i].size = query[i].size * scale;
    landmark.keypoints[i].angle = std::fmod(query[i].angle + rotation + 360.0f, 360.0f);
  }
  return landmark;
}

std::vector<cv::KeyPoint> QueryKeypoints(int n, std::mt19937* rng) {
  std::uniform_real_distribution<float> coord(0.0f, 600.0f);
  std::vector<cv::KeyPoint> keypoints;
  for (int i = 0; i < n; ++i) {
    keypoints.emplace_back(cv::Point2f(coord(*rng), coord(*rng) * 0.6f), 4.0f, 30.0f);
  }
  return keypoints;
}

// Every query row i matched to row i of landmark `slot` at place `place`.
void MatchAll(IndexResult* found, int64_t place, int32_t slot, LandmarkId landmark, int n) {
  LandmarkMatch match;
  match.query_object = 0;
  match.landmark = landmark;
  match.place = PlaceId(place);
  for (int i = 0; i < n; ++i) {
    match.matches.push_back({i, i, 0});
    found->place_points[PlaceId(place)].push_back({0, i, slot, i, 0.0f});
  }
  found->objects.push_back(match);
}

TEST(LoopDecisionTest, MatchesWithInconsistentOrientationAreDropped) {
  std::mt19937 rng(8);
  const std::vector<cv::KeyPoint> query = QueryKeypoints(50, &rng);
  LandmarkIndex index{LandmarkIndexOptions()};
  index.AddPlace({PlaceId(0), "a", 0, 0, 1});
  Landmark landmark = ShiftedLandmark(0, 0, query, &rng);
  for (int i = 30; i < 50; ++i) landmark.keypoints[i].angle = 120.0f;  // 90 degrees off
  index.Add(landmark);
  IndexResult found;
  MatchAll(&found, 0, 0, LandmarkId(0), 50);
  const Place place{PlaceId(0), "a", 0, 0, 1};
  LoopDecisionOptions options;
  options.max_inliers_per_landmark = 0;
  std::vector<PlaceMatch> ranked = RankPlaces(
      found, {query}, 0, index, [&](PlaceId) { return &place; }, options);
  ASSERT_EQ(ranked.size(), 1u);
  EXPECT_EQ(ranked[0].matched_descriptors, 30);
  options.orientation_tolerance = 0;  // off: every match is kept
  ranked = RankPlaces(
      found, {query}, 0, index, [&](PlaceId) { return &place; }, options);
  EXPECT_EQ(ranked[0].matched_descriptors, 50);
}

TEST(LoopDecisionTest, OneLandmarkScoresAtMostTheCap) {
  std::mt19937 rng(9);
  const std::vector<cv::KeyPoint> query = QueryKeypoints(40, &rng);
  LandmarkIndex index{LandmarkIndexOptions()};
  index.AddPlace({PlaceId(0), "a", 0, 0, 1});
  index.Add(ShiftedLandmark(0, 0, query, &rng));
  IndexResult found;
  MatchAll(&found, 0, 0, LandmarkId(0), 40);
  const Place place{PlaceId(0), "a", 0, 0, 1};
  LoopDecisionOptions options;
  const std::vector<PlaceMatch> ranked = RankPlaces(
      found, {query}, 0, index, [&](PlaceId) { return &place; }, options);
  ASSERT_EQ(ranked.size(), 1u);
  EXPECT_GE(ranked[0].inliers, 38);
  EXPECT_EQ(ranked[0].score, options.max_inliers_per_landmark);
}

// Five consecutive places see the query's scene at different distances (feature sizes scaled
// by exp(-0.2 (k - 2))); place 1 has the most inliers, place 2 the query's scale. The answer is
// place 2, with place 1's score.
TEST(LoopDecisionTest, LocalizesAtTheNeighbourWithTheQueryScale) {
  std::mt19937 rng(10);
  const std::vector<cv::KeyPoint> query = QueryKeypoints(60, &rng);
  LandmarkIndex index{LandmarkIndexOptions()};
  std::vector<Place> places;
  IndexResult found;
  for (int k = 0; k < 5; ++k) {
    places.push_back({PlaceId(k), "a", k, 0, 1, 640});
    index.AddPlace(places.back());
    const float scale = std::exp(-0.2f * static_cast<float>(k - 2));
    index.Add(ShiftedLandmark(k, k, query, &rng, scale));
    MatchAll(&found, k, k, LandmarkId(k), k == 1 ? 60 : 50);
  }
  LoopDecisionOptions options;
  options.max_inliers_per_landmark = 0;
  const std::vector<PlaceMatch> ranked = RankPlaces(
      found, {query}, 640, index, [&](PlaceId id) { return &places[id.value()]; }, options);
  ASSERT_FALSE(ranked.empty());
  EXPECT_EQ(ranked[0].place.sequence, 2);
  EXPECT_NEAR(ranked[0].log_scale, 0.0, 1e-6);
  EXPECT_GE(ranked[0].score, 58);   // place 1's inliers
  options.localization_window = 0;  // off: the best place answers
  const std::vector<PlaceMatch> best = RankPlaces(
      found, {query}, 640, index, [&](PlaceId id) { return &places[id.value()]; }, options);
  EXPECT_EQ(best[0].place.sequence, 1);
}

}  // namespace
}  // namespace placerec
