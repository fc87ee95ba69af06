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

#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace placerec {

class GrownKdTree {
 public:
  // A branch not taken during a search: the subtree at `node`, at least `mindist` away.
  struct Branch {
    int32_t node;
    float mindist;
  };
  // A neighbour found: the point's index and its squared Euclidean distance.
  struct Found {
    int32_t point;
    float distance;
  };

  // Adds `point` (128 bytes, kept alive by the caller while the tree is used) as point size().
  void Add(const uint8_t* point);

  size_t size() const { return points_.size(); }
  // Memory held by the tree (nodes and the point table), bytes.
  size_t MemoryBytes() const {
    return nodes_.capacity() * sizeof(Node) + points_.capacity() * sizeof(points_[0]);
  }

  // The up to `k` nearest points of `query` into `found`, closest first. The search compares
  // `checks` leaves (more while fewer than k were found) and follows the closest untaken branches
  // first (FLANN SearchParams::checks; eps 0). `heap` is scratch space, reused between calls.
  void Search(const uint8_t* query, int k, int checks, std::vector<Branch>* heap,
              std::vector<Found>* found) const;

  // Writes the tree in pre-order through `writer` (`writer->save(value)` for each value): for
  // every node its split dimension (a leaf: its point's index), its split value and whether it is
  // a leaf; 9 bytes per node, FLANN's own node encoding.
  template <typename Writer>
  void Save(Writer* writer) const;
  // Replaces this tree with one Save wrote over `points` (the same points, in the same order).
  // Throws std::runtime_error when what is read is no such tree (an index out of range, a point
  // that is no leaf or a leaf twice, a short read thrown by the reader).
  template <typename Reader>
  void Load(std::vector<const uint8_t*> points, Reader* reader);

 private:
  static constexpr int32_t kNone = -1;
  struct Node {
    int32_t feature;  // an inner node's split dimension; a leaf's point index
    float value;      // an inner node's split value: points below it go to child1
    int32_t child1 = kNone;
    int32_t child2 = kNone;
    bool leaf() const { return child1 == kNone; }
  };
  int32_t NewNode(int32_t feature, float value);

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
    const bool leaf = node.leaf();
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
  if (n > static_cast<size_t>(INT32_MAX / 2)) throw std::runtime_error("too many points");
  nodes_.reserve(2 * n - 1);
  std::vector<bool> seen(n, false);
  size_t leaves = 0;
  std::vector<int32_t> stack = {NewNode(0, 0)};
  while (!stack.empty()) {
    const int32_t at = stack.back();
    stack.pop_back();
    int32_t feature = 0;
    float value = 0;
    bool leaf = false;
    reader->load(feature);
    reader->load(value);
    reader->load(leaf);
    if (leaf) {
      if (feature < 0 || static_cast<size_t>(feature) >= n || seen[feature]) {
        throw std::runtime_error("a leaf holds point " + std::to_string(feature) + " of " +
                                 std::to_string(n) + " (or one seen before)");
      }
      seen[feature] = true;
      ++leaves;
      nodes_[at].feature = feature;
      nodes_[at].value = value;
      continue;
    }
    if (feature < 0 || feature >= 128 || nodes_.size() + 2 > 2 * n - 1) {
      throw std::runtime_error("an inner node splits dimension " + std::to_string(feature) +
                               " or the tree has more nodes than 2n - 1");
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
