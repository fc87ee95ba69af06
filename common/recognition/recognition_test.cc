// Tests of the recognition module's building blocks (seed §5.3-5.6): descriptor matching, the
// descriptor index, the range tree, the colour filter and landmark selection. The landmark index
// and the loop decision have their own tests (landmark_index_test.cc, loop_decision_test.cc).
#include <algorithm>
#include <limits>
#include <random>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "common/recognition/colour_filter.h"
#include "common/recognition/descriptor_index.h"
#include "common/recognition/descriptor_matching.h"
#include "common/recognition/landmark_selector.h"
#include "common/recognition/range_tree.h"
#include "common/recognition/recognition_test_util.h"

namespace placerec {
namespace {

using recognition_test::Noisy;
using recognition_test::RandomDescriptors;

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

// Every vector implementation against the plain loop, not only the one this processor chooses:
// extremes both ways and random rows at every byte offset (unaligned loads).
TEST(DescriptorMatchingTest, EveryImplementationIsExact) {
  const auto implementations = SquaredDistanceImplementations();
  ASSERT_GE(implementations.size(), 1u);
  const auto reference = implementations.front().second;
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> byte(0, 255);
  std::vector<uint8_t> x(128 + 16);
  std::vector<uint8_t> y(128 + 16);
  for (const auto& [name, distance] : implementations) {
    SCOPED_TRACE(name);
    std::vector<uint8_t> zeros(128, 0);
    std::vector<uint8_t> full(128, 255);
    EXPECT_EQ(distance(zeros.data(), full.data()), 128 * 255 * 255);
    EXPECT_EQ(distance(full.data(), zeros.data()), 128 * 255 * 255);
    for (int trial = 0; trial < 200; ++trial) {
      for (uint8_t& v : x) v = static_cast<uint8_t>(byte(rng));
      for (uint8_t& v : y) v = static_cast<uint8_t>(byte(rng));
      const int offset = trial % 16;
      EXPECT_EQ(distance(x.data() + offset, y.data()), reference(x.data() + offset, y.data()));
    }
  }
}

// The many-rows form gives every row's SquaredDistance, on a continuous matrix, on a column
// range of a wider one (a row step other than 128) and with extreme values.
TEST(DescriptorMatchingTest, DistancesToManyRowsAreEachRowsDistance) {
  std::mt19937 rng(13);
  const cv::Mat rows = RandomDescriptors(37, &rng);
  cv::Mat wide(40, 128 + 48, CV_8U);
  cv::randu(wide, cv::Scalar::all(0), cv::Scalar::all(256));
  wide.row(3).colRange(5, 133).setTo(255);
  const cv::Mat strided = wide.colRange(5, 133);
  const cv::Mat query = RandomDescriptors(2, &rng);
  cv::Mat zeros(1, 128, CV_8U, cv::Scalar(0));
  for (const cv::Mat& train : {rows, strided}) {
    for (const cv::Mat& q : {query.row(0), query.row(1), zeros}) {
      std::vector<int> out(static_cast<size_t>(train.rows), -1);
      SquaredDistances(q.ptr<uint8_t>(0), train, out.data());
      for (int r = 0; r < train.rows; ++r) {
        EXPECT_EQ(out[r], SquaredDistance(q.ptr<uint8_t>(0), train.ptr<uint8_t>(r))) << r;
      }
    }
  }
  std::vector<int> out(1, -1);
  SquaredDistances(zeros.ptr<uint8_t>(0), strided.row(3), out.data());
  EXPECT_EQ(out[0], 128 * 255 * 255);
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

// Both search methods: exact points, owners and rows, beyond the graph's first allocation (1,024
// points), closest first; the same additions give the same answers in a second index.
TEST(DescriptorIndexTest, BothMethodsFindNoisyCopiesClosestFirstAndDeterministically) {
  for (const DescriptorSearch method : {DescriptorSearch::kFlann, DescriptorSearch::kHnsw}) {
    SCOPED_TRACE(method == DescriptorSearch::kHnsw ? "hnsw" : "flann");
    DescriptorIndexOptions options;
    options.method = method;
    DescriptorIndex first(options);
    DescriptorIndex second(options);
    std::mt19937 rng(5);
    std::vector<cv::Mat> blocks;
    for (int owner = 0; owner < 60; ++owner) {
      blocks.push_back(RandomDescriptors(40, &rng));
      first.Add(owner, blocks.back());
      second.Add(owner, blocks.back());
    }
    ASSERT_EQ(first.size(), 2400u);
    cv::Mat queries;
    std::vector<std::pair<int, int>> truth;
    for (int i = 0; i < 100; ++i) {
      const int owner = (i * 7) % 60;
      const int row = (i * 13) % 40;
      queries.push_back(Noisy(blocks[owner].row(row), &rng, 4));
      truth.emplace_back(owner, row);
    }
    std::vector<std::vector<DescriptorIndex::Neighbour>> a;
    std::vector<std::vector<DescriptorIndex::Neighbour>> b;
    first.Search(queries, 4, &a);
    second.Search(queries, 4, &b);
    int found = 0;
    for (int q = 0; q < queries.rows; ++q) {
      ASSERT_EQ(a[q].size(), 4u);
      for (size_t j = 1; j < a[q].size(); ++j) EXPECT_LE(a[q][j - 1].distance, a[q][j].distance);
      if (a[q][0].owner == truth[q].first && a[q][0].row == truth[q].second) ++found;
      ASSERT_EQ(b[q].size(), a[q].size());
      for (size_t j = 0; j < a[q].size(); ++j) {
        EXPECT_EQ(a[q][j].owner, b[q][j].owner);
        EXPECT_EQ(a[q][j].row, b[q][j].row);
      }
    }
    // Random rows are far apart and the copies close: a working index finds nearly all.
    EXPECT_GE(found, 95);
  }
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
  // Beyond int's range: clamped (was undefined; INT_MIN in practice, an empty range).
  CountRange(3, 2.0 / 3.0, 1e9, &lo, &hi);
  EXPECT_EQ(lo, 2);
  EXPECT_EQ(hi, std::numeric_limits<int>::max());
}

// A stored keypoint angle that is NaN or infinite (a damaged map) indexed outside the orientation
// histogram; such a change now counts as inconsistent and the others are judged as before.
TEST(DescriptorMatchingTest, AnOrientationChangeThatIsNoNumberIsInconsistent) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const std::vector<bool> kept = ConsistentOrientation({10, 12, nan, 11, inf, -inf, 170}, 20);
  EXPECT_EQ(kept, (std::vector<bool>{true, true, false, true, false, false, false}));
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

}  // namespace
}  // namespace placerec
