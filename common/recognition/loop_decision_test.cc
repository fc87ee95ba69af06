// Tests of the loop decision (loop_decision.h; seed §5.7 step 6): candidate places ranked by
// matched descriptors or by geometric inliers, the orientation filter, the inlier caps,
// localization among the best place's neighbours, and what is (not) verified.
#include <cmath>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "common/recognition/landmark_index.h"
#include "common/recognition/loop_decision.h"
#include "common/recognition/recognition_test_util.h"
#include "common/util/options_test_util.h"

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
  options = LoopDecisionOptions();
  options.localization_score_fraction = 1.5;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("localization_score_fraction"), std::string::npos) << error;
  options = LoopDecisionOptions();
  options.noise_inliers = -1;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("noise_inliers"), std::string::npos) << error;
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
    places.push_back({PlaceId(k), "a", k, k * 1000000LL, 1, 640});
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
  EXPECT_GE(ranked[0].score, 58);           // place 1's inliers
  options.localization_window_seconds = 0;  // off: the best place answers
  const std::vector<PlaceMatch> best = RankPlaces(
      found, {query}, 640, index, [&](PlaceId id) { return &places[id.value()]; }, options);
  EXPECT_EQ(best[0].place.sequence, 1);
}

// A robot whose clock stands still (or a camera far faster than 10 Hz) puts many places within
// the localization window of the best one: at most max_verified_places of them are verified as
// its neighbours, the nearest first, besides the max_verified_places checked by match count.
TEST(LoopDecisionTest, NeighboursVerifiedAreBounded) {
  std::mt19937 rng(14);
  const std::vector<cv::KeyPoint> query = QueryKeypoints(60, &rng);
  LandmarkIndex index{LandmarkIndexOptions()};
  std::vector<Place> places;
  IndexResult found;
  const int kPlaces = 100;
  for (int k = 0; k < kPlaces; ++k) {
    places.push_back({PlaceId(k), "a", k, /*utime=*/0, 1, 640});
    index.AddPlace(places.back());
    index.Add(ShiftedLandmark(k, k, query, &rng));
    MatchAll(&found, k, k, LandmarkId(k), k == 50 ? 60 : 50);
  }
  LoopDecisionOptions options;
  options.max_inliers_per_landmark = 0;
  options.max_matches = kPlaces;  // every place comes back, verified or not
  const std::vector<PlaceMatch> ranked = RankPlaces(
      found, {query}, 640, index, [&](PlaceId id) { return &places[id.value()]; }, options);
  ASSERT_EQ(static_cast<int>(ranked.size()), kPlaces);
  int verified = 0;
  for (const PlaceMatch& match : ranked) verified += match.inliers > 0 ? 1 : 0;
  EXPECT_LE(verified, 2 * options.max_verified_places);
  EXPECT_GE(verified, options.max_verified_places);
}

// Every out-of-range option is refused, with a message that names it.
TEST(LoopDecisionTest, EachBadValueIsNamedInTheError) {
  options_test::ExpectEachRefusedByName<LoopDecisionOptions>({
      {"orientation_tolerance", [](LoopDecisionOptions* o) { o->orientation_tolerance = -1; }},
      {"orientation_tolerance", [](LoopDecisionOptions* o) { o->orientation_tolerance = 181; }},
      {"ransac_threshold", [](LoopDecisionOptions* o) { o->ransac_threshold = -2; }},
      {"ransac_confidence", [](LoopDecisionOptions* o) { o->ransac_confidence = 1; }},
      {"ransac_confidence", [](LoopDecisionOptions* o) { o->ransac_confidence = 0; }},
      {"max_inliers_per_landmark",
       [](LoopDecisionOptions* o) { o->max_inliers_per_landmark = -1; }},
      {"ransac_iterations", [](LoopDecisionOptions* o) { o->ransac_iterations = 0; }},
      {"min_verification_points", [](LoopDecisionOptions* o) { o->min_verification_points = -1; }},
      {"max_verified_places", [](LoopDecisionOptions* o) { o->max_verified_places = 0; }},
      {"max_matches", [](LoopDecisionOptions* o) { o->max_matches = 0; }},
      {"min_score", [](LoopDecisionOptions* o) { o->min_score = -1; }},
      {"localization_window_seconds",
       [](LoopDecisionOptions* o) { o->localization_window_seconds = 1e13; }},
  });
}

// One place per robot (so no place neighbours another), each with one landmark whose keypoints
// are the query's shifted sideways; query row i matches row i for the first counts[p] rows.
struct SeparatePlaces {
  std::vector<cv::KeyPoint> query;
  LandmarkIndex index{LandmarkIndexOptions()};
  std::vector<Place> places;
  IndexResult found;

  SeparatePlaces(const std::vector<int>& counts, std::mt19937* rng)
      : query(QueryKeypoints(60, rng)) {
    for (int p = 0; p < static_cast<int>(counts.size()); ++p) {
      places.push_back({PlaceId(p), "robot" + std::to_string(p), 0, 0, 1});
      index.AddPlace(places.back());
      index.Add(ShiftedLandmark(p, p, query, rng));
      MatchAll(&found, p, p, LandmarkId(p), counts[p]);
    }
  }
  std::vector<PlaceMatch> Rank(const LoopDecisionOptions& options) const {
    return RankPlaces(
        found, {query}, 0, index, [this](PlaceId id) { return &places[id.value()]; }, options);
  }
};

// Without the geometric check a place scores its matched descriptors; more is better, and a
// tie goes to the lower place id. At most max_matches places come back.
TEST(LoopDecisionTest, WithoutVerificationPlacesRankByMatchedDescriptors) {
  std::mt19937 rng(11);
  const SeparatePlaces places({30, 50, 40, 50}, &rng);
  LoopDecisionOptions options;
  options.geometric_verification = false;
  const std::vector<PlaceMatch> ranked = places.Rank(options);
  ASSERT_EQ(ranked.size(), 4u);
  const int64_t order[] = {1, 3, 2, 0};
  const double scores[] = {50, 50, 40, 30};
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(ranked[i].place.id, PlaceId(order[i])) << i;
    EXPECT_EQ(ranked[i].score, scores[i]) << i;
    EXPECT_EQ(ranked[i].matched_descriptors, static_cast<int>(scores[i])) << i;
    EXPECT_EQ(ranked[i].point_pairs.size(), static_cast<size_t>(scores[i])) << i;
    EXPECT_EQ(ranked[i].inliers, -1) << i;  // not verified
    EXPECT_EQ(ranked[i].matched_landmarks, 1) << i;
  }
  options.max_matches = 2;
  const std::vector<PlaceMatch> two = places.Rank(options);
  ASSERT_EQ(two.size(), 2u);
  EXPECT_EQ(two[0].place.id, PlaceId(1));
  EXPECT_EQ(two[1].place.id, PlaceId(3));
}

// A place with fewer orientation-consistent matches than min_verification_points is not
// checked and scores 0, however consistent its matches; so is a place beyond
// max_verified_places.
TEST(LoopDecisionTest, PlacesNotVerifiedScoreZero) {
  std::mt19937 rng(12);
  const SeparatePlaces places({40, 9, 35}, &rng);
  LoopDecisionOptions options;
  options.max_inliers_per_landmark = 0;
  std::vector<PlaceMatch> ranked = places.Rank(options);
  ASSERT_EQ(ranked.size(), 3u);
  EXPECT_EQ(ranked[0].place.id, PlaceId(0));
  EXPECT_GE(ranked[0].inliers, 38);
  EXPECT_EQ(ranked[0].score, ranked[0].inliers);
  EXPECT_EQ(ranked[1].place.id, PlaceId(2));
  EXPECT_GE(ranked[1].inliers, 33);
  EXPECT_EQ(ranked[2].place.id, PlaceId(1));
  EXPECT_EQ(ranked[2].matched_descriptors, 9);
  EXPECT_EQ(ranked[2].inliers, 0);
  EXPECT_EQ(ranked[2].score, 0);
  EXPECT_TRUE(ranked[2].point_pairs.empty());

  options.max_verified_places = 1;
  ranked = places.Rank(options);
  ASSERT_EQ(ranked.size(), 3u);
  EXPECT_EQ(ranked[0].place.id, PlaceId(0));
  EXPECT_GE(ranked[0].inliers, 38);
  for (size_t i = 1; i < 3; ++i) {
    EXPECT_EQ(ranked[i].score, 0) << i;
    EXPECT_EQ(ranked[i].inliers, 0) << i;
  }
  EXPECT_EQ(ranked[1].place.id, PlaceId(1));  // ties at 0 go to the lower id
}

// The object pairs of a place list every (query object, landmark) match with the landmark's
// box; matched_landmarks counts distinct landmarks. A place found by place-level matches only
// (distinctive votes) has none.
TEST(LoopDecisionTest, ObjectPairsAndBoxesComeFromTheIndex) {
  std::mt19937 rng(13);
  const std::vector<cv::KeyPoint> query = QueryKeypoints(30, &rng);
  LandmarkIndex index{LandmarkIndexOptions()};
  const Place places[2] = {{PlaceId(0), "a", 0, 0, 2}, {PlaceId(1), "b", 0, 0, 1}};
  index.AddPlace(places[0]);
  index.AddPlace(places[1]);
  Landmark first = ShiftedLandmark(0, 0, query, &rng);
  first.box = cv::Rect(10, 20, 30, 40);
  Landmark second = ShiftedLandmark(1, 0, query, &rng);
  second.box = cv::Rect(100, 20, 50, 60);
  index.Add(first);
  index.Add(second);
  index.Add(ShiftedLandmark(2, 1, query, &rng));
  IndexResult found;
  const std::vector<std::pair<int, int64_t>> object_pairs = {{0, 0}, {1, 1}, {2, 0}};
  for (const auto& [object, landmark] : object_pairs) {
    LandmarkMatch match;
    match.query_object = object;
    match.landmark = LandmarkId(landmark);
    match.place = PlaceId(0);
    found.objects.push_back(match);
  }
  for (int i = 0; i < 30; ++i) {
    found.place_points[PlaceId(0)].push_back({0, i, 0, i, 0.0f});
    found.place_points[PlaceId(1)].push_back({0, i, 2, i, 0.0f});
  }
  LoopDecisionOptions options;
  options.geometric_verification = false;
  const std::vector<PlaceMatch> ranked = RankPlaces(
      found, {query}, 0, index, [&places](PlaceId id) { return &places[id.value()]; }, options);
  ASSERT_EQ(ranked.size(), 2u);
  const PlaceMatch& a = ranked[0];
  EXPECT_EQ(a.place.id, PlaceId(0));
  EXPECT_EQ(a.matched_landmarks, 2);
  EXPECT_EQ(a.object_pairs, (std::vector<std::pair<int, LandmarkId>>{
                                {0, LandmarkId(0)}, {1, LandmarkId(1)}, {2, LandmarkId(0)}}));
  EXPECT_EQ(a.landmark_boxes, (std::vector<cv::Rect>{first.box, second.box, first.box}));
  const PlaceMatch& b = ranked[1];
  EXPECT_EQ(b.place.id, PlaceId(1));
  EXPECT_EQ(b.matched_landmarks, 0);
  EXPECT_TRUE(b.object_pairs.empty());
  EXPECT_TRUE(b.landmark_boxes.empty());
  EXPECT_EQ(b.matched_descriptors, 30);
  EXPECT_EQ(b.point_landmarks, std::vector<LandmarkId>(30, LandmarkId(2)));
}

// With max_inliers_per_cell = 1 a place scores the grid cells of the query frame its inliers
// fall in, not the inliers: here two keypoints share each cell.
TEST(LoopDecisionTest, InliersCrowdedInOneCellCountOnce) {
  std::mt19937 rng(14);
  std::uniform_real_distribution<float> jitter(2.0f, 46.0f);
  std::vector<cv::KeyPoint> query;
  for (int cell = 0; cell < 20; ++cell) {
    const cv::Point2f corner(48.0f * static_cast<float>(cell % 10),
                             48.0f * static_cast<float>(3 * (cell / 10)));
    for (int k = 0; k < 2; ++k) {
      query.emplace_back(corner + cv::Point2f(jitter(rng), jitter(rng)), 4.0f, 30.0f);
    }
  }
  LandmarkIndex index{LandmarkIndexOptions()};
  const Place place{PlaceId(0), "a", 0, 0, 1};
  index.AddPlace(place);
  index.Add(ShiftedLandmark(0, 0, query, &rng));
  IndexResult found;
  MatchAll(&found, 0, 0, LandmarkId(0), 40);
  LoopDecisionOptions options;
  options.max_inliers_per_landmark = 0;
  options.max_inliers_per_cell = 1;
  const std::vector<PlaceMatch> ranked = RankPlaces(
      found, {query}, 0, index, [&](PlaceId) { return &place; }, options);
  ASSERT_EQ(ranked.size(), 1u);
  EXPECT_GE(ranked[0].inliers, 38);
  std::set<std::pair<int, int>> cells;
  for (const auto& [p, q] : ranked[0].point_pairs) {
    cells.emplace(static_cast<int>(p.x) / options.inlier_cell_size,
                  static_cast<int>(p.y) / options.inlier_cell_size);
  }
  EXPECT_LE(cells.size(), 20u);
  EXPECT_GE(cells.size(), 18u);
  EXPECT_EQ(ranked[0].score, static_cast<double>(cells.size()));
  EXPECT_LT(ranked[0].score, ranked[0].inliers);
}

}  // namespace
}  // namespace placerec
