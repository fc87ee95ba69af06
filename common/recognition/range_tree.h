// The range tree of seed §5.6: landmark objects keyed by their SIFT count (texture), answering
// "every object whose count lies in [lo, hi]" in O(log T + W). A balanced binary search tree
// (std::map, red-black) holds one node per distinct count; in-order traversal plays the role of
// the seed's linked leaves, and the values of one count sit together in a vector.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <map>
#include <vector>

namespace placerec {

template <typename Value>
class RangeTree {
 public:
  void Insert(int key, const Value& value) {
    tree_[key].push_back(value);
    ++size_;
  }

  // Calls visit(key, value) for every value with lo <= key <= hi, in increasing key order and,
  // within a key, insertion order.
  template <typename Visit>
  void ForEachInRange(int lo, int hi, Visit&& visit) const {
    if (lo > hi) return;
    for (auto it = tree_.lower_bound(lo); it != tree_.end() && it->first <= hi; ++it) {
      for (const Value& value : it->second) visit(it->first, value);
    }
  }

  std::vector<Value> Query(int lo, int hi) const {
    std::vector<Value> values;
    ForEachInRange(lo, hi, [&values](int, const Value& value) { values.push_back(value); });
    return values;
  }

  size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }

 private:
  std::map<int, std::vector<Value>> tree_;
  size_t size_ = 0;
};

// The key range a query object with `count` keypoints looks at (seed §5.6: about [2n/3, 4n/3]).
// Ends beyond int's range are clamped to it.
inline void CountRange(int count, double low_factor, double high_factor, int* lo, int* hi) {
  const auto clamped = [](double value) {
    return static_cast<int>(std::clamp(value, static_cast<double>(std::numeric_limits<int>::min()),
                                       static_cast<double>(std::numeric_limits<int>::max())));
  };
  *lo = clamped(std::floor(count * low_factor));
  *hi = clamped(std::ceil(count * high_factor));
}

}  // namespace placerec
