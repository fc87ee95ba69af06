#include "common/segmentation/region_graph.h"

#include <algorithm>
#include <cstdint>
#include <limits>

#include <glog/logging.h>

namespace placerec {

namespace {

// Counts unit boundary edges per unordered pair of regions: open addressing on the key
// (low id << 32 | high id), doubling at half load. Most pixels of a boundary repeat the pair of
// the previous pixel, so the last key is cached.
class BoundaryCounter {
 public:
  explicit BoundaryCounter(size_t expected_pairs) {
    size_t capacity = 64;
    while (capacity < 2 * expected_pairs) capacity *= 2;
    keys_.assign(capacity, kEmpty);
    counts_.assign(capacity, 0);
  }

  void Add(int a, int b) {
    const uint64_t key = a < b ? (static_cast<uint64_t>(a) << 32) | static_cast<uint32_t>(b)
                               : (static_cast<uint64_t>(b) << 32) | static_cast<uint32_t>(a);
    if (key == last_key_) {
      ++counts_[last_slot_];
      return;
    }
    size_t slot = Find(key);
    if (keys_[slot] == kEmpty) {
      if (2 * (size_ + 1) > keys_.size()) {
        Grow();
        slot = Find(key);
      }
      keys_[slot] = key;
      ++size_;
    }
    ++counts_[slot];
    last_key_ = key;
    last_slot_ = slot;
  }

  template <typename F>
  void ForEach(F&& f) const {
    for (size_t i = 0; i < keys_.size(); ++i) {
      if (keys_[i] == kEmpty) continue;
      f(static_cast<int>(keys_[i] >> 32), static_cast<int>(keys_[i] & 0xffffffffu), counts_[i]);
    }
  }

 private:
  static constexpr uint64_t kEmpty = std::numeric_limits<uint64_t>::max();

  size_t Find(uint64_t key) const {
    const size_t mask = keys_.size() - 1;
    size_t slot = static_cast<size_t>((key * 0x9E3779B97F4A7C15ull) >> 20) & mask;
    while (keys_[slot] != kEmpty && keys_[slot] != key) slot = (slot + 1) & mask;
    return slot;
  }

  void Grow() {
    std::vector<uint64_t> old_keys;
    std::vector<int> old_counts;
    old_keys.swap(keys_);
    old_counts.swap(counts_);
    keys_.assign(old_keys.size() * 2, kEmpty);
    counts_.assign(old_keys.size() * 2, 0);
    for (size_t i = 0; i < old_keys.size(); ++i) {
      if (old_keys[i] == kEmpty) continue;
      const size_t slot = Find(old_keys[i]);
      keys_[slot] = old_keys[i];
      counts_[slot] = old_counts[i];
    }
    last_key_ = kEmpty;
  }

  std::vector<uint64_t> keys_;
  std::vector<int> counts_;
  size_t size_ = 0;
  uint64_t last_key_ = kEmpty;
  size_t last_slot_ = 0;
};

}  // namespace

int RegionGraph::SharedBoundary(int a, int b) const {
  CHECK(a >= 0 && a < size() && b >= 0 && b < size())
      << "region ids " << a << ", " << b << " outside 0.." << size() - 1;
  const auto& list = neighbours[a];
  const auto it =
      std::lower_bound(list.begin(), list.end(), b,
                       [](const std::pair<int, int>& n, int id) { return n.first < id; });
  return it != list.end() && it->first == b ? it->second : 0;
}

RegionGraph BuildRegionGraph(const cv::Mat& labels, int num_regions, const cv::Mat& lab) {
  CHECK_EQ(labels.type(), CV_32S) << "labels must be CV_32S";
  CHECK_GE(num_regions, 0);
  const bool has_lab = !lab.empty();
  if (has_lab) {
    CHECK_EQ(lab.type(), CV_32FC3) << "lab must be CV_32FC3";
    CHECK(lab.size() == labels.size()) << "lab and labels differ in size";
  }
  const int rows = labels.rows;
  const int cols = labels.cols;
  const size_t n = static_cast<size_t>(num_regions);

  std::vector<int> area(n, 0);
  std::vector<int> perimeter(n, 0);
  std::vector<int64_t> sum_x(n, 0);
  std::vector<int64_t> sum_y(n, 0);
  std::vector<cv::Vec3d> sum_lab(n, cv::Vec3d(0, 0, 0));
  std::vector<int> min_x(n, std::numeric_limits<int>::max());
  std::vector<int> min_y(n, std::numeric_limits<int>::max());
  std::vector<int> max_x(n, -1);
  std::vector<int> max_y(n, -1);
  BoundaryCounter boundaries(4 * n);

  for (int y = 0; y < rows; ++y) {
    const int* row = labels.ptr<int>(y);
    const int* below = y + 1 < rows ? labels.ptr<int>(y + 1) : nullptr;
    const cv::Vec3f* lab_row = has_lab ? lab.ptr<cv::Vec3f>(y) : nullptr;
    for (int x = 0; x < cols; ++x) {
      const int l = row[x];
      CHECK(l >= 0 && l < num_regions)
          << "label " << l << " at (" << x << ", " << y << ") outside 0.." << num_regions - 1;
      ++area[l];
      sum_x[l] += x;
      sum_y[l] += y;
      min_x[l] = std::min(min_x[l], x);
      max_x[l] = std::max(max_x[l], x);
      min_y[l] = std::min(min_y[l], y);
      max_y[l] = std::max(max_y[l], y);
      if (has_lab) {
        sum_lab[l][0] += lab_row[x][0];
        sum_lab[l][1] += lab_row[x][1];
        sum_lab[l][2] += lab_row[x][2];
      }
      if (x + 1 < cols && row[x + 1] != l) {
        ++perimeter[l];
        ++perimeter[row[x + 1]];
        boundaries.Add(l, row[x + 1]);
      }
      if (below != nullptr && below[x] != l) {
        ++perimeter[l];
        ++perimeter[below[x]];
        boundaries.Add(l, below[x]);
      }
    }
  }
  // Unit edges on the image border.
  if (rows > 0 && cols > 0) {
    const int* top = labels.ptr<int>(0);
    const int* bottom = labels.ptr<int>(rows - 1);
    for (int x = 0; x < cols; ++x) {
      ++perimeter[top[x]];
      ++perimeter[bottom[x]];
    }
    for (int y = 0; y < rows; ++y) {
      const int* row = labels.ptr<int>(y);
      ++perimeter[row[0]];
      ++perimeter[row[cols - 1]];
    }
  }

  RegionGraph graph;
  graph.regions.resize(n);
  graph.neighbours.resize(n);
  for (size_t i = 0; i < n; ++i) {
    RegionStats& r = graph.regions[i];
    r.area = area[i];
    r.perimeter = perimeter[i];
    if (area[i] == 0) continue;
    const double inv = 1.0 / area[i];
    r.centroid = cv::Point2d(sum_x[i] * inv, sum_y[i] * inv);
    r.box = cv::Rect(min_x[i], min_y[i], max_x[i] - min_x[i] + 1, max_y[i] - min_y[i] + 1);
    r.mean_lab =
        cv::Vec3f(static_cast<float>(sum_lab[i][0] * inv), static_cast<float>(sum_lab[i][1] * inv),
                  static_cast<float>(sum_lab[i][2] * inv));
  }
  boundaries.ForEach([&graph](int a, int b, int length) {
    graph.neighbours[a].emplace_back(b, length);
    graph.neighbours[b].emplace_back(a, length);
  });
  for (auto& list : graph.neighbours) std::sort(list.begin(), list.end());
  return graph;
}

}  // namespace placerec
