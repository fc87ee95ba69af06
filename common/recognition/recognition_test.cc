#include <algorithm>
#include <cmath>
#include <random>
#include <set>

#include <gtest/gtest.h>

#include "common/recognition/colour_filter.h"
#include "common/recognition/descriptor_index.h"
#include "common/recognition/descriptor_matching.h"
#include "common/recognition/landmark_index.h"
#include "common/recognition/landmark_selector.h"
#include "common/recognition/loop_decision.h"
#include "common/recognition/range_tree.h"

namespace placerec {
namespace {

// Random "descriptors": rows of uniform bytes, far apart from each other in 128 dimensions.
cv::Mat RandomDescriptors(int rows, std::mt19937* rng) {
  cv::Mat d(rows, 128, CV_8U);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < 128; ++c) d.at<uint8_t>(r, c) = static_cast<uint8_t>(byte(*rng));
  }
  return d;
}

// The same rows with a little noise, as a second view of the same object would give.
cv::Mat Noisy(const cv::Mat& d, std::mt19937* rng, int amplitude = 6) {
  cv::Mat out = d.clone();
  std::uniform_int_distribution<int> noise(-amplitude, amplitude);
  for (int r = 0; r < d.rows; ++r) {
    for (int c = 0; c < 128; ++c) {
      out.at<uint8_t>(r, c) = cv::saturate_cast<uint8_t>(d.at<uint8_t>(r, c) + noise(*rng));
    }
  }
  return out;
}

Landmark MakeLandmark(int64_t id, int64_t place, const cv::Mat& descriptors, int sift_count,
                      std::vector<float> peaks = {}) {
  Landmark landmark;
  landmark.id = LandmarkId(id);
  landmark.place = PlaceId(place);
  landmark.descriptors = descriptors;
  landmark.sift_count = sift_count;
  landmark.colour.peaks = std::move(peaks);
  for (int r = 0; r < descriptors.rows; ++r) {
    landmark.keypoints.emplace_back(cv::Point2f(10.0f * r, 5.0f * (r % 7)), 3.0f);
  }
  return landmark;
}

TEST(DescriptorMatchingTest, SquaredDistance) {
  cv::Mat a(1, 128, CV_8U, cv::Scalar(10));
  cv::Mat b(1, 128, CV_8U, cv::Scalar(13));
  EXPECT_EQ(SquaredDistance(a.ptr<uint8_t>(0), b.ptr<uint8_t>(0)), 128 * 9);
  // Extremes both ways (the SIMD path widens bytes before subtracting) and random rows against
  // the plain sum.
  cv::Mat zeros(1, 128, CV_8U, cv::Scalar(0));
  cv::Mat full(1, 128, CV_8U, cv::Scalar(255));
  EXPECT_EQ(SquaredDistance(zeros.ptr<uint8_t>(0), full.ptr<uint8_t>(0)), 128 * 255 * 255);
  EXPECT_EQ(SquaredDistance(full.ptr<uint8_t>(0), zeros.ptr<uint8_t>(0)), 128 * 255 * 255);
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int trial = 0; trial < 100; ++trial) {
    uint8_t x[128];
    uint8_t y[128];
    int expected = 0;
    for (int i = 0; i < 128; ++i) {
      x[i] = static_cast<uint8_t>(byte(rng));
      y[i] = static_cast<uint8_t>(byte(rng));
      expected += (x[i] - y[i]) * (x[i] - y[i]);
    }
    EXPECT_EQ(SquaredDistance(x, y), expected);
  }
}

TEST(DescriptorMatchingTest, RatioTestFindsTrueMatchesAndRejectsAmbiguousOnes) {
  std::mt19937 rng(1);
  const cv::Mat train = RandomDescriptors(30, &rng);
  const cv::Mat query = Noisy(train.rowRange(0, 10), &rng);
  std::vector<DescriptorMatch> matches = MatchRatioTest(query, train, 0.8);
  ASSERT_EQ(matches.size(), 10u);
  for (const DescriptorMatch& m : matches) EXPECT_EQ(m.query, m.train);

  // A train set with two copies of the same row is ambiguous for that row.
  cv::Mat doubled;
  cv::vconcat(train, train.row(3), doubled);
  matches = MatchRatioTest(query, doubled, 0.8);
  EXPECT_EQ(matches.size(), 9u);
  for (const DescriptorMatch& m : matches) EXPECT_NE(m.query, 3);
}

TEST(DescriptorMatchingTest, EachTrainRowIsMatchedOnce) {
  std::mt19937 rng(2);
  const cv::Mat train = RandomDescriptors(5, &rng);
  cv::Mat query;
  cv::vconcat(Noisy(train.row(0), &rng, 2), Noisy(train.row(0), &rng, 8), query);
  const std::vector<DescriptorMatch> matches = MatchRatioTest(query, train, 0.8);
  ASSERT_EQ(matches.size(), 1u);
  EXPECT_EQ(matches[0].query, 0);  // the closer one keeps the train row
}

TEST(DescriptorIndexTest, FindsExactPointsWithOwnerAndRow) {
  std::mt19937 rng(3);
  DescriptorIndex index{DescriptorIndexOptions()};
  const cv::Mat a = RandomDescriptors(50, &rng);
  const cv::Mat b = RandomDescriptors(70, &rng);
  index.Add(7, a);
  index.Add(9, b);
  EXPECT_EQ(index.size(), 120u);
  std::vector<std::vector<DescriptorIndex::Neighbour>> neighbours;
  cv::Mat queries;
  cv::vconcat(a.row(12), b.row(44), queries);
  index.Search(queries, 2, &neighbours);
  ASSERT_EQ(neighbours.size(), 2u);
  EXPECT_EQ(neighbours[0][0].owner, 7);
  EXPECT_EQ(neighbours[0][0].row, 12);
  EXPECT_EQ(neighbours[0][0].distance, 0.0f);
  EXPECT_EQ(neighbours[1][0].owner, 9);
  EXPECT_EQ(neighbours[1][0].row, 44);
}

TEST(RangeTreeTest, ReturnsExactlyTheValuesInRange) {
  std::mt19937 rng(4);
  std::uniform_int_distribution<int> key(0, 300);
  RangeTree<int> tree;
  std::vector<std::pair<int, int>> all;
  for (int v = 0; v < 2000; ++v) {
    const int k = key(rng);
    tree.Insert(k, v);
    all.emplace_back(k, v);
  }
  EXPECT_EQ(tree.size(), 2000u);
  for (int trial = 0; trial < 200; ++trial) {
    int lo = key(rng);
    int hi = key(rng);
    if (lo > hi) std::swap(lo, hi);
    std::vector<int> got = tree.Query(lo, hi);
    std::vector<int> expected;
    for (const auto& [k, v] : all) {
      if (k >= lo && k <= hi) expected.push_back(v);
    }
    std::sort(got.begin(), got.end());
    ASSERT_EQ(got, expected) << "[" << lo << ", " << hi << "]";
  }
  EXPECT_TRUE(tree.Query(10, 5).empty());
}

TEST(RangeTreeTest, CountRangeFollowsTheSeed) {
  int lo = 0;
  int hi = 0;
  CountRange(30, 2.0 / 3.0, 4.0 / 3.0, &lo, &hi);  // seed §5.6: 30 keypoints -> 20..40
  EXPECT_EQ(lo, 20);
  EXPECT_EQ(hi, 40);
}

TEST(ColourFilterTest, SeedRules) {
  ColourFilterOptions options;
  ColourSignature red{{0.88f}};
  ColourSignature near_red{{0.75f}};
  ColourSignature blue{{-2.0f}};
  ColourSignature red_and_blue{{0.88f, -2.0f}};
  ColourSignature unknown;
  EXPECT_TRUE(ColoursCompatible(red, near_red, options));
  EXPECT_FALSE(ColoursCompatible(red, blue, options));
  EXPECT_TRUE(ColoursCompatible(unknown, blue, options));
  EXPECT_TRUE(ColoursCompatible(red, red_and_blue, options));
  // A multi-peak query only matches multi-peak objects.
  EXPECT_FALSE(ColoursCompatible(red_and_blue, red, options));
  options.multi_peak_needs_multi_peak = false;
  EXPECT_TRUE(ColoursCompatible(red_and_blue, red, options));
  // With any_peak off only the highest peaks are compared.
  options.any_peak = false;
  EXPECT_FALSE(ColoursCompatible(blue, red_and_blue, options));
}

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

TEST(LandmarkSelectorTest, ObjectsSeenInThePreviousThreeFramesAreLandmarks) {
  std::mt19937 rng(6);
  const cv::Mat a = RandomDescriptors(20, &rng);
  const cv::Mat b = RandomDescriptors(20, &rng);
  const cv::Mat c = RandomDescriptors(20, &rng);
  LandmarkSelector selector{LandmarkSelectorOptions()};

  // Frame 0: objects A and B. Nothing to compare with yet.
  EXPECT_TRUE(selector.Select({a, b}).landmarks.empty());
  selector.Remember({a, b});

  // Frame 1: A seen again (12 of its features) and the new C: only A is a landmark, with the 12
  // tracked rows.
  cv::Mat a_again = Noisy(a.rowRange(0, 12), &rng);
  LandmarkSelection selection = selector.Select({RandomDescriptors(15, &rng), a_again, c});
  ASSERT_EQ(selection.landmarks, std::vector<int>({1}));
  ASSERT_EQ(selection.tracked_rows[0].size(), 12u);
  // Select does not change the selector.
  EXPECT_EQ(selector.history_size(), 1);

  // Five matching features are not enough (the seed asks for at least six).
  selection = selector.Select({Noisy(b.rowRange(0, 5), &rng)});
  EXPECT_TRUE(selection.landmarks.empty());

  // After three more frames, frame 0 is forgotten: B no longer makes a landmark.
  selector.Remember({c});
  selector.Remember({RandomDescriptors(20, &rng)});
  selector.Remember({RandomDescriptors(20, &rng)});
  EXPECT_EQ(selector.history_size(), 3);
  EXPECT_TRUE(selector.Select({Noisy(b, &rng)}).landmarks.empty());
  EXPECT_EQ(selector.Select({Noisy(c, &rng)}).landmarks, std::vector<int>({0}));
}

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
  options.localization_window_seconds = 0;  // off: the best place answers
  const std::vector<PlaceMatch> best = RankPlaces(
      found, {query}, 640, index, [&](PlaceId id) { return &places[id.value()]; }, options);
  EXPECT_EQ(best[0].place.sequence, 1);
}

}  // namespace
}  // namespace placerec
