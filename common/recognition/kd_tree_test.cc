#include "common/recognition/kd_tree.h"

#include <algorithm>
#include <cstring>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>
#include <flann/flann.hpp>

namespace placerec {
namespace {

constexpr int kSize = 128;

// Descriptors in clusters (as SIFT descriptors of one scene are), with exact duplicates and
// equal distances, where ties decide the order.
std::vector<uint8_t> Points(int n, uint32_t seed) {
  std::mt19937 random(seed);
  std::vector<uint8_t> centres(16 * kSize);
  for (uint8_t& v : centres) v = static_cast<uint8_t>(random() % 256);
  std::vector<uint8_t> points(static_cast<size_t>(n) * kSize);
  for (int i = 0; i < n; ++i) {
    const uint8_t* centre = &centres[(random() % 16) * kSize];
    uint8_t* p = &points[static_cast<size_t>(i) * kSize];
    if (i > 0 && random() % 20 == 0) {  // an exact copy of an earlier point
      std::memcpy(p, &points[(random() % i) * kSize], kSize);
      continue;
    }
    for (int d = 0; d < kSize; ++d) {
      const int noisy = centre[d] + static_cast<int>(random() % 33) - 16;
      p[d] = static_cast<uint8_t>(std::clamp(noisy, 0, 255));
    }
  }
  return points;
}

// Queries near stored points (as a revisit's descriptors are) and far from all (another place's).
std::vector<uint8_t> Queries(const std::vector<uint8_t>& points, int n, uint32_t seed) {
  std::mt19937 random(seed);
  std::vector<uint8_t> queries = Points(n / 2, seed);
  const size_t stored = points.size() / kSize;
  for (int i = n / 2; i < n; ++i) {
    const uint8_t* near = &points[(random() % stored) * kSize];
    for (int d = 0; d < kSize; ++d) {
      const int noisy = near[d] + static_cast<int>(random() % 9) - 4;
      queries.push_back(static_cast<uint8_t>(std::clamp(noisy, 0, 255)));
    }
  }
  return queries;
}

// FLANN 1.9's KDTreeIndex with one tree, grown as DescriptorIndex grew it before GrownKdTree:
// built on the first point, the others inserted without a rebuild.
struct FlannTree {
  explicit FlannTree(std::vector<uint8_t>* points)
      : index(flann::Matrix<uint8_t>(points->data(), 1, kSize), flann::KDTreeIndexParams(1)) {
    index.buildIndex();
    const size_t n = points->size() / kSize;
    if (n > 1) {
      index.addPoints(flann::Matrix<uint8_t>(points->data() + kSize, n - 1, kSize),
                      std::numeric_limits<float>::max());
    }
  }
  flann::KDTreeIndex<flann::L2<uint8_t>> index;
};

TEST(GrownKdTreeTest, FindsWhatFlannsGrownTreeFinds) {
  std::vector<uint8_t> points = Points(3000, 1);
  const std::vector<uint8_t> queries = Queries(points, 300, 2);
  FlannTree flann_tree(&points);
  GrownKdTree tree;
  for (size_t i = 0; i < points.size() / kSize; ++i) tree.Add(&points[i * kSize]);
  ASSERT_EQ(tree.size(), 3000u);

  std::vector<GrownKdTree::Found> found;
  // k above 250: FLANN keeps the neighbours in another result set, which breaks ties otherwise.
  // checks above the tree's size: every leaf is compared.
  for (const int checks : {1, 8, 32, 256, 5000}) {
    for (const int k : {1, 2, 5, 16, 250, 251, 400}) {
      SCOPED_TRACE("checks " + std::to_string(checks) + ", k " + std::to_string(k));
      const int rows = static_cast<int>(queries.size() / kSize);
      std::vector<size_t> indices(static_cast<size_t>(rows) * k);
      std::vector<float> distances(static_cast<size_t>(rows) * k);
      flann::Matrix<uint8_t> query_matrix(const_cast<uint8_t*>(queries.data()), rows, kSize);
      flann::Matrix<size_t> index_matrix(indices.data(), rows, k);
      flann::Matrix<float> distance_matrix(distances.data(), rows, k);
      flann::SearchParams params(checks);
      params.cores = 1;
      flann_tree.index.knnSearch(query_matrix, index_matrix, distance_matrix, k, params);
      // One query at a time, and all of them one by one and in step (the first 299: a count
      // that does not fill the last group).
      std::vector<std::vector<GrownKdTree::Found>> many;
      std::vector<std::vector<GrownKdTree::Found>> in_step;
      tree.SearchMany(queries.data(), rows - 1, kSize, k, checks, &many,
                      GrownKdTree::Order::kOneByOne);
      tree.SearchMany(queries.data(), rows - 1, kSize, k, checks, &in_step,
                      GrownKdTree::Order::kInStep);
      ASSERT_EQ(many.size(), static_cast<size_t>(rows - 1));
      ASSERT_EQ(in_step.size(), static_cast<size_t>(rows - 1));
      int differences = 0;
      int differences_many = 0;
      int differences_in_step = 0;
      for (int q = 0; q < rows; ++q) {
        tree.Search(&queries[static_cast<size_t>(q) * kSize], k, checks, &found);
        ASSERT_EQ(found.size(), static_cast<size_t>(k));
        for (int j = 0; j < k; ++j) {
          if (found[j].point != static_cast<int32_t>(index_matrix[q][j]) ||
              found[j].distance != distance_matrix[q][j]) {
            ++differences;
          }
        }
        if (q == rows - 1) continue;
        ASSERT_EQ(many[q].size(), static_cast<size_t>(k));
        ASSERT_EQ(in_step[q].size(), static_cast<size_t>(k));
        for (int j = 0; j < k; ++j) {
          if (many[q][j].point != static_cast<int32_t>(index_matrix[q][j]) ||
              many[q][j].distance != distance_matrix[q][j]) {
            ++differences_many;
          }
          if (in_step[q][j].point != static_cast<int32_t>(index_matrix[q][j]) ||
              in_step[q][j].distance != distance_matrix[q][j]) {
            ++differences_in_step;
          }
        }
      }
      EXPECT_EQ(differences, 0);
      EXPECT_EQ(differences_many, 0);
      EXPECT_EQ(differences_in_step, 0);
    }
  }
}

TEST(GrownKdTreeTest, SmallTrees) {
  std::vector<uint8_t> points = Points(3, 3);
  GrownKdTree tree;
  std::vector<GrownKdTree::Found> found;
  tree.Search(points.data(), 2, 32, &found);
  EXPECT_TRUE(found.empty());
  tree.Add(points.data());
  tree.Search(points.data(), 2, 32, &found);  // fewer points than asked for
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].point, 0);
  EXPECT_EQ(found[0].distance, 0.0f);
  tree.Add(points.data() + kSize);
  tree.Add(points.data() + 2 * kSize);
  tree.Search(points.data() + 2 * kSize, 3, 1, &found);  // goes on until 3 are found
  ASSERT_EQ(found.size(), 3u);
  EXPECT_EQ(found[0].point, 2);
  EXPECT_LE(found[1].distance, found[2].distance);
  std::vector<std::vector<GrownKdTree::Found>> many;
  tree.SearchMany(points.data(), 0, kSize, 3, 1, &many);
  EXPECT_TRUE(many.empty());
  tree.SearchMany(points.data() + 2 * kSize, 1, kSize, 3, 1, &many);
  ASSERT_EQ(many.size(), 1u);
  ASSERT_EQ(many[0].size(), 3u);
  EXPECT_EQ(many[0][0].point, 2);
}

// Writes and reads values as the snapshot's archives do.
struct Bytes {
  std::vector<uint8_t> data;
  size_t next = 0;
  template <typename T>
  void save(const T& value) {
    const uint8_t* p = reinterpret_cast<const uint8_t*>(&value);
    data.insert(data.end(), p, p + sizeof(value));
  }
  template <typename T>
  void load(T& value) {
    if (next + sizeof(value) > data.size()) throw std::runtime_error("short");
    std::memcpy(&value, data.data() + next, sizeof(value));
    next += sizeof(value);
  }
};

std::vector<const uint8_t*> Table(const std::vector<uint8_t>& points) {
  std::vector<const uint8_t*> table;
  for (size_t i = 0; i < points.size() / kSize; ++i) table.push_back(&points[i * kSize]);
  return table;
}

TEST(GrownKdTreeTest, ALoadedTreeAnswersAsTheSavedOne) {
  const std::vector<uint8_t> points = Points(500, 4);
  const std::vector<uint8_t> queries = Points(50, 5);
  GrownKdTree tree;
  for (const uint8_t* p : Table(points)) tree.Add(p);
  Bytes bytes;
  tree.Save(&bytes);
  EXPECT_EQ(bytes.data.size(), 9u * (2 * 500 - 1));  // 9 bytes per node
  GrownKdTree loaded;
  loaded.Load(Table(points), &bytes);
  EXPECT_EQ(bytes.next, bytes.data.size());
  std::vector<GrownKdTree::Found> a, b;
  for (size_t q = 0; q < queries.size() / kSize; ++q) {
    tree.Search(&queries[q * kSize], 4, 16, &a);
    loaded.Search(&queries[q * kSize], 4, 16, &b);
    ASSERT_EQ(a.size(), b.size());
    for (size_t j = 0; j < a.size(); ++j) {
      EXPECT_EQ(a[j].point, b[j].point);
      EXPECT_EQ(a[j].distance, b[j].distance);
    }
  }
  // Growing on after loading continues as the saved tree would have.
  const std::vector<uint8_t> more = Points(20, 6);
  for (const uint8_t* p : Table(more)) {
    tree.Add(p);
    loaded.Add(p);
  }
  Bytes again_a, again_b;
  tree.Save(&again_a);
  loaded.Save(&again_b);
  EXPECT_EQ(again_a.data, again_b.data);
}

// One node of Save's encoding.
void PutNode(Bytes* bytes, int32_t feature, float value, uint8_t leaf) {
  bytes->save(feature);
  bytes->save(value);
  bytes->save(leaf);
}

TEST(GrownKdTreeTest, LoadRefusesWhatIsNoTreeOfThePoints) {
  const std::vector<uint8_t> points = Points(50, 7);
  GrownKdTree tree;
  for (const uint8_t* p : Table(points)) tree.Add(p);
  Bytes good;
  tree.Save(&good);
  // What Load throws for `bytes` over the first `points_given` points; empty when it loads.
  auto error = [&](Bytes bytes, size_t points_given = 50) -> std::string {
    GrownKdTree loaded;
    std::vector<const uint8_t*> table = Table(points);
    table.resize(points_given);
    try {
      loaded.Load(table, &bytes);
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "";
  };
  auto contains = [](const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
  };
  EXPECT_EQ(error(good), "");
  // A leaf beyond the points (a one-point tree, so no node limit comes first).
  Bytes beyond;
  PutNode(&beyond, 1, 0, 1);
  EXPECT_TRUE(contains(error(beyond, 1), "holds point 1 of 1")) << error(beyond, 1);
  Bytes short_read = good;
  short_read.data.resize(good.data.size() - 1);
  EXPECT_EQ(error(short_read), "short");
  // The first node is the root, an inner node: a split dimension past the descriptor.
  Bytes bad_dimension = good;
  const int32_t dimension = 128;
  std::memcpy(bad_dimension.data.data(), &dimension, 4);
  EXPECT_TRUE(contains(error(bad_dimension), "splits dimension 128"));
  // Split values a grown tree never has.
  for (const float value : {-1.0f, 255.5f, 256.0f, std::numeric_limits<float>::quiet_NaN(),
                            std::numeric_limits<float>::infinity()}) {
    Bytes bad_value = good;
    std::memcpy(bad_value.data.data() + 4, &value, 4);
    EXPECT_TRUE(contains(error(bad_value), "splits at")) << value;
  }
  // A leaf flag other than 0 or 1.
  Bytes bad_flag = good;
  bad_flag.data[8] = 2;
  EXPECT_TRUE(contains(error(bad_flag), "leaf flag of 2"));
  // Every leaf names the first point: a point twice.
  Bytes twice = good;
  for (size_t at = 0; at + 9 <= twice.data.size(); at += 9) {
    if (twice.data[at + 8] == 1) std::memset(&twice.data[at], 0, 4);
  }
  EXPECT_TRUE(contains(error(twice), "or one seen before"));
  // A root that claims to be a leaf leaves the other points out.
  Bytes one_leaf = good;
  one_leaf.data[8] = 1;
  std::memset(one_leaf.data.data(), 0, 4);
  EXPECT_TRUE(contains(error(one_leaf), "holds 1 of 50 points"));
  // Inner nodes down one side only: more nodes than 50 points have, long before the bytes end.
  Bytes deep;
  for (int i = 0; i < 60; ++i) PutNode(&deep, 0, 0, 0);
  EXPECT_TRUE(contains(error(deep), "more nodes than 2n - 1"));
}

}  // namespace
}  // namespace placerec
