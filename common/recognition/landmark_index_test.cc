// Tests of the landmark index (landmark_index.h; seed §5.6): retrieval of stored objects through
// the texture range and the colour filter, object-level and place-level matches, distinctive
// votes, slots and counts, with both searches where they must agree.
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/recognition/landmark_index.h"
#include "common/recognition/recognition_test_util.h"

namespace placerec {
namespace {

using recognition_test::MakeLandmark;
using recognition_test::Noisy;
using recognition_test::RandomDescriptors;

// Ten places of one robot, 100 frames apart, each with four landmarks of 30 random descriptors
// (landmark i at place i / 4, coloured `peaks`); their descriptors go to *stored, in id order.
void AddTenPlaces(LandmarkIndex* index, std::mt19937* rng, std::vector<cv::Mat>* stored,
                  const std::vector<float>& peaks = {}) {
  for (int p = 0; p < 10; ++p) index->AddPlace({PlaceId(p), "robot", p * 100, p * 100000000LL, 4});
  for (int i = 0; i < 40; ++i) {
    stored->push_back(RandomDescriptors(30, rng));
    index->Add(MakeLandmark(i, i / 4, stored->back(), 30, peaks));
  }
}

class LandmarkIndexTest : public ::testing::TestWithParam<IndexSearch> {};

TEST_P(LandmarkIndexTest, RetrievesTheRightLandmarkAndRespectsFilters) {
  std::mt19937 rng(5);
  LandmarkIndexOptions options;
  options.search = GetParam();
  LandmarkIndex index(options);
  std::vector<cv::Mat> stored;
  AddTenPlaces(&index, &rng, &stored, {0.1f});
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

TEST(LandmarkIndexOptionsTest, DefaultsPassAndBadValuesAreNamed) {
  std::string error;
  EXPECT_TRUE(LandmarkIndexOptions().Check(&error)) << error;
  // The seed's texture range (§5.6) is the default.
  EXPECT_DOUBLE_EQ(LandmarkIndexOptions().count_range_low, 2.0 / 3.0);
  EXPECT_DOUBLE_EQ(LandmarkIndexOptions().count_range_high, 4.0 / 3.0);
  EXPECT_EQ(LandmarkIndexOptions().matching.min_matches, 7);
  for (const double low : {-0.1, 1.5}) {
    LandmarkIndexOptions bad;
    bad.count_range_low = low;
    EXPECT_FALSE(bad.Check(&error)) << low;
    EXPECT_NE(error.find("count_range_low"), std::string::npos) << error;
  }
  LandmarkIndexOptions bad;
  bad.count_range_high = 0.5;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_NE(error.find("count_range_high"), std::string::npos) << error;
  bad.count_range_high = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(bad.Check(&error));
  bad = LandmarkIndexOptions();
  bad.matching.ratio = 1.5;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_NE(error.find("ratio"), std::string::npos) << error;
  // Windows are taken in microseconds: at most a day, far from overflowing.
  bad = LandmarkIndexOptions();
  bad.vote_window_seconds = 1e13;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_NE(error.find("vote_window_seconds"), std::string::npos) << error;
  for (const int exact : {-1, 1001}) {
    bad = LandmarkIndexOptions();
    bad.exact_places = exact;
    EXPECT_FALSE(bad.Check(&error)) << exact;
    EXPECT_NE(error.find("exact_places"), std::string::npos) << error;
  }
}

// Slots are insertion order whatever the ids; counts grow with every landmark added.
TEST(LandmarkIndexSlotsTest, SlotsFollowInsertionAndUnknownIdsHaveNone) {
  std::mt19937 rng(21);
  LandmarkIndex index{LandmarkIndexOptions()};
  EXPECT_EQ(index.num_landmarks(), 0u);
  EXPECT_EQ(index.num_descriptors(), 0u);
  index.AddPlace({PlaceId(1), "robot", 0, 0, 2});
  index.Add(MakeLandmark(7, 1, RandomDescriptors(30, &rng), 30));
  EXPECT_EQ(index.num_landmarks(), 1u);
  EXPECT_EQ(index.num_descriptors(), 30u);
  index.Add(MakeLandmark(3, 1, RandomDescriptors(20, &rng), 25));
  EXPECT_EQ(index.num_landmarks(), 2u);
  EXPECT_EQ(index.num_descriptors(), 50u);
  EXPECT_EQ(index.SlotOf(LandmarkId(7)), 0);
  EXPECT_EQ(index.SlotOf(LandmarkId(3)), 1);
  EXPECT_EQ(index.landmark(1).id, LandmarkId(3));
  EXPECT_EQ(index.landmark(1).sift_count, 25);
  EXPECT_EQ(index.SlotOf(LandmarkId(5)), -1);    // between the two
  EXPECT_EQ(index.SlotOf(LandmarkId(100)), -1);  // beyond every id
  EXPECT_EQ(index.SlotOf(LandmarkId()), -1);     // the invalid id
  // Ids need not be dense: one of 2^42 (a PostgreSQL sequence moved on) sized a vector by id,
  // and opening such a map ended in std::bad_alloc.
  index.Add(MakeLandmark(int64_t{1} << 42, 1, RandomDescriptors(10, &rng), 10));
  EXPECT_EQ(index.SlotOf(LandmarkId(int64_t{1} << 42)), 2);
  EXPECT_EQ(index.SlotOf(LandmarkId((int64_t{1} << 42) - 1)), -1);
}

// A large upper texture factor (meant as "no upper limit") overflowed the key range to nothing:
// no landmark was a candidate. The range is clamped to int's.
TEST(LandmarkIndexCandidatesTest, AHugeUpperTextureFactorStillFindsTheLandmark) {
  std::mt19937 rng(23);
  LandmarkIndexOptions options;
  options.count_range_high = 1e9;
  std::string error;
  ASSERT_TRUE(options.Check(&error)) << error;
  LandmarkIndex index{options};
  index.AddPlace({PlaceId(1), "robot", 0, 0, 1});
  const cv::Mat descriptors = RandomDescriptors(30, &rng);
  index.Add(MakeLandmark(1, 1, descriptors, 30));
  IndexQuery query{30, ColourSignature(), descriptors};
  const std::vector<int32_t> candidates = index.Candidates(query);
  EXPECT_EQ(candidates, std::vector<int32_t>{0});
}

// Candidates (seed §5.6): SIFT counts in [2n/3, 4n/3], both ends included, and a compatible
// colour; each filter can be turned off.
TEST(LandmarkIndexCandidatesTest, TextureRangeIsInclusiveAndFiltersCanBeTurnedOff) {
  std::mt19937 rng(22);
  const int counts[] = {19, 20, 30, 40, 41};
  auto build = [&](const LandmarkIndexOptions& options) {
    auto index = std::make_unique<LandmarkIndex>(options);
    index->AddPlace({PlaceId(0), "robot", 0, 0, 5});
    for (int i = 0; i < 5; ++i) {
      index->Add(MakeLandmark(i, 0, RandomDescriptors(10, &rng), counts[i], {0.1f}));
    }
    return index;
  };
  IndexQuery query;
  query.sift_count = 30;  // range 20..40
  query.colour.peaks = {0.15f};
  EXPECT_EQ(build(LandmarkIndexOptions())->Candidates(query), (std::vector<int32_t>{1, 2, 3}));
  IndexQuery blue = query;
  blue.colour.peaks = {-2.0f};
  EXPECT_TRUE(build(LandmarkIndexOptions())->Candidates(blue).empty());
  // A query without a colour signature passes the colour filter.
  IndexQuery colourless = query;
  colourless.colour.peaks.clear();
  EXPECT_EQ(build(LandmarkIndexOptions())->Candidates(colourless), (std::vector<int32_t>{1, 2, 3}));

  LandmarkIndexOptions any_count;
  any_count.use_count_range = false;
  EXPECT_EQ(build(any_count)->Candidates(query), (std::vector<int32_t>{0, 1, 2, 3, 4}));
  LandmarkIndexOptions any_colour;
  any_colour.use_colour_filter = false;
  EXPECT_EQ(build(any_colour)->Candidates(blue), (std::vector<int32_t>{1, 2, 3}));
}

TEST_P(LandmarkIndexTest, EmptyIndexOrEmptyQueryFindsNothing) {
  std::mt19937 rng(23);
  LandmarkIndexOptions options;
  options.search = GetParam();
  LandmarkIndex index(options);
  auto all_places = [](PlaceId) { return true; };
  IndexQuery query;
  query.sift_count = 30;
  query.descriptors = RandomDescriptors(30, &rng);
  IndexResult found = index.Query({query}, all_places);
  EXPECT_TRUE(found.objects.empty());
  EXPECT_TRUE(found.place_points.empty());
  index.AddPlace({PlaceId(0), "robot", 0, 0, 1});
  index.Add(MakeLandmark(0, 0, query.descriptors.clone(), 30));
  found = index.Query({}, all_places);
  EXPECT_TRUE(found.objects.empty());
  EXPECT_TRUE(found.place_points.empty());
}

// Several query objects at once: each finds its own landmark, and the matches say which query
// object and row they came from, sorted by query object.
TEST_P(LandmarkIndexTest, EachQueryObjectFindsItsOwnLandmark) {
  std::mt19937 rng(24);
  LandmarkIndexOptions options;
  options.search = GetParam();
  LandmarkIndex index(options);
  std::vector<cv::Mat> stored;
  AddTenPlaces(&index, &rng, &stored);
  std::vector<IndexQuery> queries(2);
  queries[0].sift_count = 30;
  queries[0].descriptors = Noisy(stored[22].rowRange(0, 15), &rng);  // place 5
  queries[1].sift_count = 30;
  queries[1].descriptors = Noisy(stored[5].rowRange(5, 17), &rng);  // place 1
  const IndexResult found = index.Query(queries, [](PlaceId) { return true; });
  ASSERT_EQ(found.objects.size(), 2u);
  EXPECT_EQ(found.objects[0].query_object, 0);
  EXPECT_EQ(found.objects[0].landmark, LandmarkId(22));
  EXPECT_EQ(found.objects[0].place, PlaceId(5));
  EXPECT_EQ(found.objects[0].matches.size(), 15u);
  EXPECT_EQ(found.objects[1].query_object, 1);
  EXPECT_EQ(found.objects[1].landmark, LandmarkId(5));
  EXPECT_EQ(found.objects[1].place, PlaceId(1));
  ASSERT_EQ(found.objects[1].matches.size(), 12u);
  for (const DescriptorMatch& m : found.objects[1].matches) EXPECT_EQ(m.train, m.query + 5);
  ASSERT_EQ(found.place_points.count(PlaceId(5)), 1u);
  ASSERT_EQ(found.place_points.count(PlaceId(1)), 1u);
  EXPECT_EQ(found.place_points.at(PlaceId(5)).size(), 15u);
  EXPECT_EQ(found.place_points.at(PlaceId(1)).size(), 12u);
  for (const PointMatch& p : found.place_points.at(PlaceId(1))) {
    EXPECT_EQ(p.query_object, 1);
    EXPECT_EQ(p.slot, index.SlotOf(LandmarkId(5)));
    EXPECT_EQ(p.train, p.query_row + 5);
  }
}

INSTANTIATE_TEST_SUITE_P(Searches, LandmarkIndexTest,
                         ::testing::Values(IndexSearch::kFlann, IndexSearch::kExhaustive));

// Descriptors outside every object of the frame form no object pair; with FLANN they still
// vote for the place they show, which then matches at place level (a corridor without objects
// is still recognised). Votes respect the place filter and can be turned off.
TEST(LandmarkIndexVotesTest, DescriptorsOutsideObjectsFindTheirPlaceByVotesOnly) {
  std::mt19937 rng(25);
  auto build = [&](const LandmarkIndexOptions& options, std::vector<cv::Mat>* stored) {
    auto index = std::make_unique<LandmarkIndex>(options);
    AddTenPlaces(index.get(), &rng, stored);
    return index;
  };
  std::vector<cv::Mat> stored;
  const std::unique_ptr<LandmarkIndex> index = build(LandmarkIndexOptions(), &stored);
  IndexQuery rest;
  // In the texture range of the stored objects: only is_object keeps it from pairing with them.
  rest.sift_count = 30;
  rest.is_object = false;
  rest.descriptors = Noisy(stored[13].rowRange(0, 20), &rng);  // place 3
  const IndexResult found = index->Query({rest}, [](PlaceId) { return true; });
  EXPECT_TRUE(found.objects.empty());
  ASSERT_EQ(found.place_points.count(PlaceId(3)), 1u);
  EXPECT_EQ(found.place_points.at(PlaceId(3)).size(), 20u);
  for (const PointMatch& p : found.place_points.at(PlaceId(3))) {
    EXPECT_EQ(index->landmark(p.slot).id, LandmarkId(13));
    EXPECT_EQ(p.train, p.query_row);
  }
  const IndexResult filtered = index->Query({rest}, [](PlaceId p) { return p != PlaceId(3); });
  EXPECT_TRUE(filtered.objects.empty());
  EXPECT_EQ(filtered.place_points.count(PlaceId(3)), 0u);

  LandmarkIndexOptions no_votes;
  no_votes.vote_places = 0;
  std::vector<cv::Mat> stored_again;
  const std::unique_ptr<LandmarkIndex> without = build(no_votes, &stored_again);
  rest.descriptors = Noisy(stored_again[13].rowRange(0, 20), &rng);
  const IndexResult unvoted = without->Query({rest}, [](PlaceId) { return true; });
  EXPECT_TRUE(unvoted.objects.empty());
  EXPECT_TRUE(unvoted.place_points.empty());

  // kExhaustive is the seed's retrieval: objects only.
  LandmarkIndexOptions exhaustive;
  exhaustive.search = IndexSearch::kExhaustive;
  std::vector<cv::Mat> stored_exhaustive;
  const std::unique_ptr<LandmarkIndex> seed = build(exhaustive, &stored_exhaustive);
  rest.descriptors = Noisy(stored_exhaustive[13].rowRange(0, 20), &rng);
  const IndexResult literal = seed->Query({rest}, [](PlaceId) { return true; });
  EXPECT_TRUE(literal.objects.empty());
  EXPECT_TRUE(literal.place_points.empty());
}

// A voted place brings its robot's places within the vote window as candidates, nearest in time
// first and at most kMaxVoteNeighbours of them: a camera fast enough to fill the window, or a
// robot whose clock stands still (every place at one time), does not make every place a
// candidate of every query, and a 10 Hz camera keeps all of its window.
TEST(LandmarkIndexVotesTest, AVotedPlaceBringsABoundedNeighbourhood) {
  std::mt19937 rng(31);
  const auto candidates = [&](int64_t spacing_us) {
    LandmarkIndex index{LandmarkIndexOptions()};
    const int places = 600;
    std::vector<cv::Mat> stored;
    for (int p = 0; p < places; ++p) {
      index.AddPlace({PlaceId(p), "robot", p, p * spacing_us, 1});
      stored.push_back(RandomDescriptors(30, &rng));
      index.Add(MakeLandmark(p, p, stored.back(), 30, {}));
    }
    IndexQuery rest;
    rest.sift_count = 30;
    rest.is_object = false;
    rest.descriptors = Noisy(stored[300].rowRange(0, 20), &rng);
    const IndexResult found = index.Query({rest}, [](PlaceId) { return true; });
    EXPECT_EQ(found.place_points.count(PlaceId(300)), 1u);
    return found.stats.candidate_places;
  };
  // 10 Hz: the default window of 3 s on each side holds 61 places, all of them candidates.
  EXPECT_EQ(candidates(100000), 61);
  // A clock standing still: every place is "within the window" of the voted one.
  EXPECT_EQ(candidates(0), LandmarkIndex::kMaxVoteNeighbours + 1);
  // 100 Hz: 600 places fit the window; the nearest are kept.
  EXPECT_EQ(candidates(10000), LandmarkIndex::kMaxVoteNeighbours + 1);
}

// 600 places of one robot whose clock stands still (all at time 0), one landmark each; the query
// holds noisy copies of place 300's descriptors.
struct StoppedClock {
  static constexpr int kPlaces = 600;
  static constexpr int kVoted = 300;
  LandmarkIndex index{LandmarkIndexOptions()};
  IndexQuery query;

  explicit StoppedClock(uint32_t seed) {
    std::mt19937 rng(seed);
    cv::Mat voted;
    for (int p = 0; p < kPlaces; ++p) {
      index.AddPlace({PlaceId(p), "robot", p, /*utime=*/0, 1});
      const cv::Mat stored = RandomDescriptors(30, &rng);
      if (p == kVoted) voted = stored;
      index.Add(MakeLandmark(p, p, stored, 30, {}));
    }
    query.sift_count = 30;
    query.is_object = false;
    query.descriptors = Noisy(voted.rowRange(0, 20), &rng);
  }
};

TEST(LandmarkIndexVotesTest, AStoppedClockBringsTheVotedPlacesSequenceNeighbours) {
  const StoppedClock map(37);
  std::set<int64_t> asked;
  const IndexResult found = map.index.Query({map.query}, [&](PlaceId place) {
    asked.insert(place.value());
    return true;
  });
  EXPECT_EQ(found.place_points.count(PlaceId(StoppedClock::kVoted)), 1u);
  EXPECT_EQ(found.stats.candidate_places, LandmarkIndex::kMaxVoteNeighbours + 1);
  // All times equal: the places inserted around the voted one, half on each side.
  const int half = LandmarkIndex::kMaxVoteNeighbours / 2;
  for (int p = StoppedClock::kVoted - half; p <= StoppedClock::kVoted + half; ++p) {
    EXPECT_EQ(asked.count(p), 1u) << p;
  }
  EXPECT_EQ(asked.count(0), 0u);
  EXPECT_EQ(asked.count(StoppedClock::kPlaces - 1), 0u);
}

// Places the caller does not allow (a robot's own recent past) take none of the voted place's
// neighbour slots: the neighbourhood holds kMaxVoteNeighbours allowed places.
TEST(LandmarkIndexVotesTest, PlacesNotAllowedTakeNoNeighbourSlot) {
  const StoppedClock map(41);
  const IndexResult found =
      map.index.Query({map.query}, [](PlaceId place) { return place.value() % 2 == 0; });
  EXPECT_EQ(found.place_points.count(PlaceId(StoppedClock::kVoted)), 1u);
  EXPECT_EQ(found.stats.candidate_places, LandmarkIndex::kMaxVoteNeighbours + 1);
}

// A revisited place whose true matches are crowded out of the neighbour lists: half of the
// query's rows have more than `knn` stored descriptors of other places nearer than their true
// match (as in a large map, where many places hold similar descriptors). The lists give the
// place only the uncrowded half; matching its best places again exactly gives it every row.
TEST(LandmarkIndexExactPlacesTest, CrowdedOutMatchesAreFoundByMatchingTheBestPlacesAgain) {
  const auto points = [](int exact_places, int* candidates) {
    std::mt19937 rng(43);
    LandmarkIndexOptions options;
    options.exact_places = exact_places;
    LandmarkIndex index(options);
    // The revisited place: one robot's place 0, 40 descriptors.
    index.AddPlace({PlaceId(0), "robot", 0, 0, 1});
    const cv::Mat stored = RandomDescriptors(40, &rng);
    index.Add(MakeLandmark(0, 0, stored, 40, {}));
    IndexQuery rest;
    rest.sift_count = 40;
    rest.is_object = false;
    rest.descriptors = Noisy(stored, &rng, 6);
    // Rows 20-39: 20 near copies each (noise 2 against the true match's 6), spread over 100
    // places of other robots, 4 per place.
    const int knn = options.matching.knn;
    const int copies = knn + 4;
    std::vector<cv::Mat> clutter(100);
    int next = 0;
    for (int row = 20; row < 40; ++row) {
      for (int c = 0; c < copies; ++c) {
        clutter[next % 100].push_back(Noisy(rest.descriptors.row(row), &rng, 2));
        ++next;
      }
    }
    for (int p = 0; p < 100; ++p) {
      index.AddPlace({PlaceId(1 + p), "other" + std::to_string(p), 0, 0, 1});
      index.Add(MakeLandmark(1 + p, 1 + p, clutter[p], clutter[p].rows, {}));
    }
    const IndexResult found = index.Query({rest}, [](PlaceId) { return true; });
    *candidates = static_cast<int>(found.stats.candidate_places);
    const auto place = found.place_points.find(PlaceId(0));
    if (place == found.place_points.end()) return std::vector<PointMatch>();
    return place->second;
  };
  int candidates = 0;
  const std::vector<PointMatch> from_lists = points(0, &candidates);
  EXPECT_EQ(candidates, 1);           // only the true place gets distinctive votes
  EXPECT_EQ(from_lists.size(), 20u);  // the uncrowded half
  const std::vector<PointMatch> exact = points(1, &candidates);
  EXPECT_EQ(candidates, 1);
  ASSERT_EQ(exact.size(), 40u);
  for (const PointMatch& p : exact) {
    EXPECT_EQ(p.slot, 0);
    EXPECT_EQ(p.train, p.query_row);
  }
}

// Five places of five robots (or of one robot along a route), 40 descriptors each; the query holds
// a noisy copy of every descriptor, of which only the first `uncrowded[p]` of place p are free of
// near copies in other places (the rest have knn + 4 nearer ones each). Place 1 also holds a
// landmark without descriptors. Returns each place's matches.
std::map<int64_t, size_t> ExactRanking(const LandmarkIndexOptions& options, IndexQueryStats* stats,
                                       const std::vector<int>& uncrowded = {10, 20, 15, 12, 12},
                                       bool one_route = false) {
  std::mt19937 rng(47);
  LandmarkIndex index(options);
  IndexQuery rest;
  rest.sift_count = 40;
  rest.is_object = false;
  std::vector<cv::Mat> clutter(200);
  int next = 0;
  for (int p = 0; p < 5; ++p) {
    // One route: one robot's places a second apart, within one vote window.
    index.AddPlace({PlaceId(p), one_route ? "robot" : "robot" + std::to_string(p), p,
                    one_route ? p * 1000000LL : 0, 1});
    const cv::Mat stored = RandomDescriptors(40, &rng);
    index.Add(MakeLandmark(p, p, stored, 40, {}));
    const cv::Mat query = Noisy(stored, &rng, 6);
    rest.descriptors.push_back(query);
    for (int row = uncrowded[p]; row < 40; ++row) {
      for (int c = 0; c < options.matching.knn + 4; ++c) {
        clutter[next++ % 200].push_back(Noisy(query.row(row), &rng, 2));
      }
    }
  }
  index.Add(MakeLandmark(5, 1, cv::Mat(), 0, {}));
  for (int c = 0; c < 200; ++c) {
    index.AddPlace({PlaceId(10 + c), "clutter" + std::to_string(c), 0, 0, 1});
    index.Add(MakeLandmark(10 + c, 10 + c, clutter[c], clutter[c].rows, {}));
  }
  const IndexResult found = index.Query({rest}, [](PlaceId) { return true; });
  *stats = found.stats;
  std::map<int64_t, size_t> points;
  for (int p = 0; p < 5; ++p) {
    const auto it = found.place_points.find(PlaceId(p));
    points[p] = it == found.place_points.end() ? 0 : it->second.size();
  }
  return points;
}

// The places with the most matches from the lists are matched exactly, ties to the lower id;
// the others keep what their lists hold.
TEST(LandmarkIndexExactPlacesTest, OnlyTheBestPlacesAreMatchedAgainTiesToTheLowerId) {
  LandmarkIndexOptions options;
  IndexQueryStats stats;
  options.exact_places = 0;
  const std::map<int64_t, size_t> lists = ExactRanking(options, &stats);
  EXPECT_EQ(lists, (std::map<int64_t, size_t>{{0, 10}, {1, 20}, {2, 15}, {3, 12}, {4, 12}}));
  EXPECT_EQ(stats.exact_places, 0);
  options.exact_places = 1;
  EXPECT_EQ(ExactRanking(options, &stats),
            (std::map<int64_t, size_t>{{0, 10}, {1, 40}, {2, 15}, {3, 12}, {4, 12}}));
  EXPECT_EQ(stats.exact_places, 1);
  options.exact_places = 3;  // places 1 and 2, then 3 before 4 (12 each)
  EXPECT_EQ(ExactRanking(options, &stats),
            (std::map<int64_t, size_t>{{0, 10}, {1, 40}, {2, 40}, {3, 40}, {4, 12}}));
  EXPECT_EQ(stats.exact_places, 3);
  EXPECT_EQ(stats.exact_comparisons, 3 * 40 * 200);  // query rows times each place's 40
  EXPECT_EQ(stats.exact_skipped, 0);
}

// Along a route, a chosen place brings its nearest candidate place on either side, matched
// exactly too; the places beyond keep their lists' matches.
TEST(LandmarkIndexExactPlacesTest, AChosenPlaceBringsItsRouteNeighbours) {
  LandmarkIndexOptions options;
  options.exact_places = 1;
  options.exact_route_neighbours = 0;
  const std::vector<int> uncrowded = {10, 12, 20, 14, 10};
  IndexQueryStats stats;
  EXPECT_EQ(ExactRanking(options, &stats, uncrowded, true),
            (std::map<int64_t, size_t>{{0, 10}, {1, 12}, {2, 40}, {3, 14}, {4, 10}}));
  options.exact_route_neighbours = 1;
  EXPECT_EQ(ExactRanking(options, &stats, uncrowded, true),
            (std::map<int64_t, size_t>{{0, 10}, {1, 40}, {2, 40}, {3, 40}, {4, 10}}));
  EXPECT_EQ(stats.exact_places, 3);
  // Robots apart: no route, no neighbours.
  EXPECT_EQ(ExactRanking(options, &stats, uncrowded, false),
            (std::map<int64_t, size_t>{{0, 10}, {1, 12}, {2, 40}, {3, 14}, {4, 10}}));
}

// The comparison budget: a place that would pass it keeps its matches from the lists, and a
// smaller one after it may still be matched.
TEST(LandmarkIndexExactPlacesTest, APlaceBeyondTheComparisonBudgetKeepsItsListMatches) {
  LandmarkIndexOptions options;
  options.exact_places = 2;
  options.exact_max_comparisons = 40 * 200;  // one place's worth
  IndexQueryStats stats;
  EXPECT_EQ(ExactRanking(options, &stats),
            (std::map<int64_t, size_t>{{0, 10}, {1, 40}, {2, 15}, {3, 12}, {4, 12}}));
  EXPECT_EQ(stats.exact_places, 1);
  EXPECT_EQ(stats.exact_skipped, 1);
  EXPECT_EQ(stats.exact_comparisons, 40 * 200);
  options.exact_max_comparisons = 40 * 200 - 1;
  EXPECT_EQ(ExactRanking(options, &stats),
            (std::map<int64_t, size_t>{{0, 10}, {1, 20}, {2, 15}, {3, 12}, {4, 12}}));
  EXPECT_EQ(stats.exact_skipped, 2);
}

}  // namespace
}  // namespace placerec
