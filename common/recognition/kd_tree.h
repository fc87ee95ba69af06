// The k-d tree behind DescriptorSearch::kFlann: FLANN 1.9's single k-d tree (Muja and Lowe 2009)
// grown one point at a time and searched best bin first, written out so that a search costs
// nothing in proportion to the tree's size. FLANN's KDTreeIndex allocates a branch heap as large
// as the tree and clears one bit per stored point for every query (to skip points a second tree
// already checked; a single tree never reaches a point twice); at millions of descriptors that
// costs more than the search itself. This tree grows exactly as FLANN's addPointToTree grows it
// and searches exactly as FLANN's getNeighbors does, so it finds the same neighbours at the same
// distances, in the same order.
//
// Points are 128-byte SIFT descriptors owned by the caller; a point's index is its insertion
// order. Nodes take 16 bytes (2n - 1 of them for n points). Not thread-safe for Add; Search is
// const and may run on several threads at once.
#pragma once

#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace placerec {

class GrownKdTree {
 public:
  // A neighbour found: the point's index and its squared Euclidean distance.
  struct Found {
    int32_t point;
    float distance;
  };

  // Adds `point` (128 bytes, kept alive by the caller while the tree is used) as point size().
  void Add(const uint8_t* point);
  // Makes room for `points` points in all, so that growing to them copies nothing.
  void Reserve(size_t points);

  size_t size() const { return points_.size(); }

  // The up to `k` nearest points of `query` into `found`, closest first. The search compares
  // `checks` leaves (more while fewer than k were found) and follows the closest untaken branches
  // first (FLANN SearchParams::checks; eps 0). Points at equal distances are kept and ordered as
  // FLANN's knnSearch keeps them (which result set it uses depends on k).
  void Search(const uint8_t* query, int k, int checks, std::vector<Found>* found) const;
  // Search for each of `count` queries (128 bytes each, `stride` bytes apart) into (*found)[i],
  // with the same answers as one Search per query. Several queries are searched in step, each
  // asking for the memory its next step reads while the others work: the tree and the
  // descriptors are far larger than the caches, and one query alone waits on nearly every node.
  //
  // Searching in step pays where the tree and its points outgrow the caches; a smaller tree is
  // searched one query at a time, which skips the bookkeeping of taking turns (the same answers
  // either way). kAuto chooses by the tree's size (kInStepMinPoints).
  enum class Order { kAuto, kOneByOne, kInStep };
  static constexpr size_t kInStepMinPoints = 1 << 14;
  void SearchMany(const uint8_t* queries, size_t count, size_t stride, int k, int checks,
                  std::vector<std::vector<Found>>* found, Order order = Order::kAuto) const;

  // Writes the tree in pre-order through `writer` (`writer->save(value)` for each value): for
  // every node its split dimension (a leaf: its point's index), its split value and whether it is
  // a leaf; 9 bytes per node, FLANN's own node encoding.
  template <typename Writer>
  void Save(Writer* writer) const;
  // Replaces this tree with one Save wrote over `points` (the same points, in the same order).
  // Throws std::runtime_error when what is read is no such tree (an index out of range, a split
  // value no grown tree has, a leaf flag other than 0 or 1, a point that is no leaf or a leaf
  // twice, more than 2n - 1 nodes, a short read thrown by the reader).
  template <typename Reader>
  void Load(std::vector<const uint8_t*> points, Reader* reader);

 private:
  // A branch not taken during a search: the subtree at `node`, at least `mindist` away.
  struct Branch {
    int32_t node;
    float mindist;
  };
  static constexpr int32_t kNone = -1;
  static constexpr size_t kMaxPoints = INT32_MAX / 2;  // 2n - 1 nodes must have int32 indices
  struct Node {
    int32_t feature;  // an inner node's split dimension; a leaf's point index
    float value;      // an inner node's split value: points below it go to child1
    int32_t child1 = kNone;
    int32_t child2 = kNone;
    bool leaf() const { return child1 == kNone; }
  };
  int32_t NewNode(int32_t feature, float value);
  // SearchMany, keeping the neighbours in `ResultSet` (one of FLANN's k-nearest result sets).
  template <typename ResultSet>
  void SearchManyWith(const uint8_t* queries, size_t count, size_t stride, int k, int checks,
                      std::vector<std::vector<Found>>* found) const;
  // The same search, one query after the other.
  template <typename ResultSet>
  void SearchOneByOneWith(const uint8_t* queries, size_t count, size_t stride, int k, int checks,
                          std::vector<std::vector<Found>>* found) const;

  std::vector<Node> nodes_;  // nodes_[0] is the root
  std::vector<const uint8_t*> points_;
};

template <typename Writer>
void GrownKdTree::Save(Writer* writer) const {
  if (nodes_.empty()) return;
  std::vector<int32_t> stack = {0};
  while (!stack.empty()) {
    const Node& node = nodes_[stack.back()];
    stack.pop_back();
    const uint8_t leaf = node.leaf() ? 1 : 0;
    writer->save(node.feature);
    writer->save(node.value);
    writer->save(leaf);
    if (!leaf) {
      stack.push_back(node.child2);
      stack.push_back(node.child1);  // read first
    }
  }
}

template <typename Reader>
void GrownKdTree::Load(std::vector<const uint8_t*> points, Reader* reader) {
  nodes_.clear();
  points_ = std::move(points);
  if (points_.empty()) return;
  const size_t n = points_.size();
  if (n > kMaxPoints) throw std::runtime_error("too many points");
  nodes_.reserve(2 * n - 1);
  std::vector<bool> seen(n, false);
  size_t leaves = 0;
  std::vector<int32_t> stack = {NewNode(0, 0)};
  while (!stack.empty()) {
    const int32_t at = stack.back();
    stack.pop_back();
    int32_t feature = 0;
    float value = 0;
    uint8_t leaf = 0;
    reader->load(feature);
    reader->load(value);
    reader->load(leaf);
    if (leaf > 1) throw std::runtime_error("a leaf flag of " + std::to_string(leaf));
    if (leaf == 1) {
      if (feature < 0 || static_cast<size_t>(feature) >= n || seen[feature]) {
        throw std::runtime_error("a leaf holds point " + std::to_string(feature) + " of " +
                                 std::to_string(n) + " (or one seen before)");
      }
      seen[feature] = true;
      ++leaves;
      nodes_[at].feature = feature;
      nodes_[at].value = 0;  // a leaf's value is never read
      continue;
    }
    if (feature < 0 || feature >= 128) {
      throw std::runtime_error("an inner node splits dimension " + std::to_string(feature));
    }
    // A grown tree splits at the integer mean of two byte values.
    if (!(value >= 0 && value <= 255 && value == std::floor(value))) {
      throw std::runtime_error("an inner node splits at " + std::to_string(value));
    }
    if (nodes_.size() + 2 > 2 * n - 1) {
      throw std::runtime_error("the tree has more nodes than 2n - 1 for " + std::to_string(n) +
                               " points");
    }
    const int32_t child1 = NewNode(0, 0);
    const int32_t child2 = NewNode(0, 0);
    nodes_[at] = Node{feature, value, child1, child2};
    stack.push_back(child2);
    stack.push_back(child1);
  }
  if (leaves != n) {
    throw std::runtime_error("the tree holds " + std::to_string(leaves) + " of " +
                             std::to_string(n) + " points");
  }
}

}  // namespace placerec
