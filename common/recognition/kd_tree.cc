#include "common/recognition/kd_tree.h"

#include <algorithm>
#include <cstdlib>
#include <type_traits>

#include <flann/util/result_set.h>

#include "common/recognition/descriptor_matching.h"
#include "common/util/logging.h"

namespace placerec {
namespace {

constexpr int kDimensions = 128;

}  // namespace

int32_t GrownKdTree::NewNode(int32_t feature, float value) {
  nodes_.push_back(Node{feature, value, kNone, kNone});
  return static_cast<int32_t>(nodes_.size() - 1);
}

void GrownKdTree::Reserve(size_t points) {
  CHECK_LE(points, kMaxPoints);
  points_.reserve(points);
  nodes_.reserve(points > 0 ? 2 * points - 1 : 0);
}

void GrownKdTree::Add(const uint8_t* point) {
  CHECK_LT(points_.size(), kMaxPoints) << "a k-d tree of more than 2^30 points";
  const int32_t index = static_cast<int32_t>(points_.size());
  points_.push_back(point);
  if (nodes_.empty()) {
    NewNode(index, 0);
    return;
  }
  // Down to the leaf the point falls in (FLANN: point[divfeat] < divval goes to child1).
  int32_t at = 0;
  while (!nodes_[at].leaf()) {
    const Node& node = nodes_[at];
    at = point[node.feature] < node.value ? node.child1 : node.child2;
  }
  // The leaf splits on the first dimension where the two points differ most, at the integer
  // mean of their values; the smaller goes to child1.
  const int32_t leaf_index = nodes_[at].feature;
  const uint8_t* leaf_point = points_[leaf_index];
  int max_span = 0;
  int feature = 0;
  for (int d = 0; d < kDimensions; ++d) {
    const int span = std::abs(point[d] - leaf_point[d]);
    if (span > max_span) {
      max_span = span;
      feature = d;
    }
  }
  const bool new_below = point[feature] < leaf_point[feature];
  const int32_t child1 = NewNode(new_below ? index : leaf_index, 0);
  const int32_t child2 = NewNode(new_below ? leaf_index : index, 0);
  nodes_[at] =
      Node{feature, static_cast<float>((point[feature] + leaf_point[feature]) / 2), child1, child2};
}

namespace {

// FLANN's knnSearch keeps the k nearest in a KNNSimpleResultSet up to KNN_HEAP_THRESHOLD (250)
// and in a KNNResultSet2 above it; the two break ties between equally distant points apart.
constexpr int kFlannHeapThreshold = 250;

}  // namespace

void GrownKdTree::Search(const uint8_t* query, int k, int checks, std::vector<Found>* found) const {
  std::vector<std::vector<Found>> one;
  SearchMany(query, 1, 0, k, checks, &one, Order::kOneByOne);
  *found = std::move(one[0]);
}

template <typename ResultSet>
void GrownKdTree::SearchOneByOneWith(const uint8_t* queries, size_t count, size_t stride, int k,
                                     int checks, std::vector<std::vector<Found>>* found) const {
  // FLANN's getNeighbors with one tree, as SearchManyWith takes its steps, for one query at a
  // time: descend from a node to a leaf, pushing the branches not taken, then take the closest
  // branch from the heap, until `checks` leaves were compared (and k found) or none is left.
  const auto farther_first = [](const Branch& a, const Branch& b) { return b.mindist < a.mindist; };
  ResultSet result(static_cast<size_t>(k));
  std::vector<Branch> heap;
  std::vector<size_t> indices;
  std::vector<float> distances;
  for (size_t q = 0; q < count; ++q) {
    const uint8_t* query = queries + q * stride;
    result.clear();
    heap.clear();
    int checked = 0;
    int32_t at = 0;
    float mindist = 0;
    while (true) {
      while (result.worstDist() >= mindist) {
        const Node& node = nodes_[at];
        if (node.leaf()) {
          if (checked >= checks && result.full()) break;
          ++checked;
          result.addPoint(static_cast<float>(SquaredDistance(points_[node.feature], query)),
                          static_cast<size_t>(node.feature));
          break;
        }
        const uint8_t value = query[node.feature];
        const float diff = value - node.value;
        const int32_t best = diff < 0 ? node.child1 : node.child2;
        const int32_t other = diff < 0 ? node.child2 : node.child1;
        const float new_distsq = mindist + diff * diff;
        if (new_distsq < result.worstDist() || !result.full()) {
          heap.push_back(Branch{other, new_distsq});
          std::push_heap(heap.begin(), heap.end(), farther_first);
        }
        at = best;
      }
      if (heap.empty() || (checked >= checks && result.full())) break;
      at = heap.front().node;
      mindist = heap.front().mindist;
      std::pop_heap(heap.begin(), heap.end(), farther_first);
      heap.pop_back();
    }
    const size_t n = result.size();
    indices.resize(n);
    distances.resize(n);
    result.copy(indices.data(), distances.data(), n, /*sorted=*/true);
    std::vector<Found>& out = (*found)[q];
    out.resize(n);
    for (size_t i = 0; i < n; ++i) out[i] = Found{static_cast<int32_t>(indices[i]), distances[i]};
  }
}

template <typename ResultSet>
void GrownKdTree::SearchManyWith(const uint8_t* queries, size_t count, size_t stride, int k,
                                 int checks, std::vector<std::vector<Found>>* found) const {
  // FLANN's getNeighbors with one tree (its searchLevel's tail recursion a loop) as a state
  // machine: one step (a node, a leaf's distance, a branch from the heap) at a time, so that
  // kInStep queries can take turns. A step in a subtree no nearer than the worst neighbour kept
  // ends its descent; a leaf is compared while fewer than `checks` were (or fewer than k found);
  // the branch not taken is kept on the heap while it may hold a nearer point.
  constexpr size_t kInStep = 8;
  // The order of FLANN's Heap<BranchSt>: std::push_heap and std::pop_heap with this comparison,
  // so that equally distant branches leave the heap in FLANN's order.
  const auto farther_first = [](const Branch& a, const Branch& b) { return b.mindist < a.mindist; };
  enum class Next { kNode, kDistance, kBranch, kIdle };
  struct Slot {
    explicit Slot(int k) : result(static_cast<size_t>(k)) {}
    ResultSet result;
    std::vector<Branch> heap;
    const uint8_t* query = nullptr;
    size_t index = 0;
    int checked = 0;
    int32_t at = 0;     // kNode: the node to visit; kDistance: the leaf's point
    float mindist = 0;  // kNode: the bound of the subtree at `at`
    Next next = Next::kIdle;
  };
  std::vector<Slot> slots;
  // No more slots than queries: each reserves room for k neighbours.
  const size_t in_step = std::min(kInStep, count);
  slots.reserve(in_step);
  for (size_t i = 0; i < in_step; ++i) slots.emplace_back(k);
  std::vector<size_t> indices;
  std::vector<float> distances;
  size_t next_query = 0;
  auto start = [&](Slot* slot) {
    if (next_query == count) {
      slot->next = Next::kIdle;
      return false;
    }
    slot->index = next_query++;
    slot->query = queries + slot->index * stride;
    slot->result.clear();
    slot->heap.clear();
    slot->checked = 0;
    slot->at = 0;
    slot->mindist = 0;
    slot->next = Next::kNode;
    __builtin_prefetch(&nodes_[0]);
    return true;
  };
  auto finish = [&](Slot* slot) {
    const size_t n = slot->result.size();
    indices.resize(n);
    distances.resize(n);
    slot->result.copy(indices.data(), distances.data(), n, /*sorted=*/true);
    std::vector<Found>& out = (*found)[slot->index];
    out.resize(n);
    for (size_t i = 0; i < n; ++i) out[i] = Found{static_cast<int32_t>(indices[i]), distances[i]};
  };
  size_t active = 0;
  for (Slot& slot : slots) active += start(&slot);
  while (active > 0) {
    for (Slot& slot : slots) {
      switch (slot.next) {
        case Next::kIdle:
          break;
        case Next::kNode: {
          if (slot.result.worstDist() < slot.mindist) {
            slot.next = Next::kBranch;
            break;
          }
          const Node& node = nodes_[slot.at];
          if (node.leaf()) {
            if (slot.checked >= checks && slot.result.full()) {
              slot.next = Next::kBranch;
              break;
            }
            ++slot.checked;
            slot.at = node.feature;
            __builtin_prefetch(points_[node.feature]);
            __builtin_prefetch(points_[node.feature] + 64);
            slot.next = Next::kDistance;
            break;
          }
          const uint8_t value = slot.query[node.feature];
          const float diff = value - node.value;
          const int32_t best = diff < 0 ? node.child1 : node.child2;
          const int32_t other = diff < 0 ? node.child2 : node.child1;
          const float new_distsq = slot.mindist + (value - node.value) * (value - node.value);
          if (new_distsq < slot.result.worstDist() || !slot.result.full()) {
            slot.heap.push_back(Branch{other, new_distsq});
            std::push_heap(slot.heap.begin(), slot.heap.end(), farther_first);
          }
          slot.at = best;
          __builtin_prefetch(&nodes_[best]);
          break;
        }
        case Next::kDistance:
          slot.result.addPoint(static_cast<float>(SquaredDistance(points_[slot.at], slot.query)),
                               static_cast<size_t>(slot.at));
          slot.next = Next::kBranch;
          break;
        case Next::kBranch:
          if (!slot.heap.empty() && (slot.checked < checks || !slot.result.full())) {
            const Branch branch = slot.heap.front();
            std::pop_heap(slot.heap.begin(), slot.heap.end(), farther_first);
            slot.heap.pop_back();
            slot.at = branch.node;
            slot.mindist = branch.mindist;
            __builtin_prefetch(&nodes_[branch.node]);
            slot.next = Next::kNode;
          } else {
            finish(&slot);
            if (!start(&slot)) --active;
          }
          break;
      }
    }
  }
}

void GrownKdTree::SearchMany(const uint8_t* queries, size_t count, size_t stride, int k, int checks,
                             std::vector<std::vector<Found>>* found, Order order) const {
  found->assign(count, {});
  if (nodes_.empty() || k <= 0 || count == 0) return;
  const bool in_step = order == Order::kInStep ||
                       (order == Order::kAuto && points_.size() >= kInStepMinPoints && count > 1);
  // FLANN keeps more than kFlannHeapThreshold neighbours in another result set (the pointer
  // names the type only).
  const auto search = [&](auto* result_type) {
    using Result = std::remove_pointer_t<decltype(result_type)>;
    if (in_step) {
      SearchManyWith<Result>(queries, count, stride, k, checks, found);
    } else {
      SearchOneByOneWith<Result>(queries, count, stride, k, checks, found);
    }
  };
  if (k > kFlannHeapThreshold) {
    search(static_cast<flann::KNNResultSet2<float>*>(nullptr));
  } else {
    search(static_cast<flann::KNNSimpleResultSet<float>*>(nullptr));
  }
}

}  // namespace placerec
