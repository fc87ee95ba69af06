#include "common/segmentation/superpixels.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <queue>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <glog/logging.h>
#include <opencv2/imgproc.hpp>

#include "common/segmentation/region_graph.h"
#include "common/util/timer.h"

namespace placerec {

bool SuperpixelOptions::Check(std::string* error) const {
  if (working_width != 0 && working_width < 16) {
    *error = "superpixel working_width must be 0 (frame size) or at least 16 pixels, got " +
             std::to_string(working_width);
    return false;
  }
  if (!(sigma >= 0.0) || !std::isfinite(sigma)) {
    *error = "superpixel sigma must be a finite value >= 0, got " + std::to_string(sigma);
    return false;
  }
  if (!(k > 0.0) || !std::isfinite(k)) {
    *error = "superpixel k must be a finite value > 0, got " + std::to_string(k);
    return false;
  }
  if (min_size < 1) {
    *error = "superpixel min_size must be at least 1 pixel, got " + std::to_string(min_size);
    return false;
  }
  if (!(min_region_fraction >= 0.0 && min_region_fraction < 0.1)) {
    *error = "superpixel min_region_fraction must be in [0, 0.1), got " +
             std::to_string(min_region_fraction);
    return false;
  }
  if (!(colour_merge_distance >= 0.0) || !std::isfinite(colour_merge_distance)) {
    *error = "superpixel colour_merge_distance must be a finite value >= 0, got " +
             std::to_string(colour_merge_distance);
    return false;
  }
  return true;
}

namespace {

// Union-find over the pixels of FH, union by size with path halving.
class DisjointSets {
 public:
  explicit DisjointSets(int n) : parent_(static_cast<size_t>(n)), size_(static_cast<size_t>(n), 1) {
    for (int i = 0; i < n; ++i) parent_[i] = i;
  }

  int Find(int x) {
    while (parent_[x] != x) {
      parent_[x] = parent_[parent_[x]];
      x = parent_[x];
    }
    return x;
  }

  // Joins two roots and returns the new root (the larger set; `a` on ties).
  int Join(int a, int b) {
    if (size_[a] < size_[b]) std::swap(a, b);
    parent_[b] = a;
    size_[a] += size_[b];
    return a;
  }

  int Size(int root) const { return size_[root]; }

 private:
  std::vector<int> parent_;
  std::vector<int> size_;
};

// Sorts 64-bit items by their upper 32 bits, stably, in three 11-bit LSD radix passes (passes
// whose digit is the same for every item are skipped).
void RadixSortByUpperWord(std::vector<uint64_t>* items) {
  constexpr int kBits = 11;
  constexpr int kBuckets = 1 << kBits;
  const size_t n = items->size();
  std::vector<std::array<uint32_t, kBuckets>> counts(3);
  for (auto& c : counts) c.fill(0);
  for (const uint64_t item : *items) {
    const uint32_t key = static_cast<uint32_t>(item >> 32);
    ++counts[0][key & (kBuckets - 1)];
    ++counts[1][(key >> kBits) & (kBuckets - 1)];
    ++counts[2][key >> (2 * kBits)];
  }
  std::vector<uint64_t> buffer(n);
  for (int pass = 0; pass < 3; ++pass) {
    std::array<uint32_t, kBuckets>& count = counts[pass];
    if (std::find(count.begin(), count.end(), static_cast<uint32_t>(n)) != count.end()) continue;
    uint32_t offset = 0;
    for (uint32_t& c : count) {
      const uint32_t here = c;
      c = offset;
      offset += here;
    }
    const int shift = 32 + pass * kBits;
    for (const uint64_t item : *items) {
      buffer[count[(item >> shift) & (kBuckets - 1)]++] = item;
    }
    items->swap(buffer);
  }
}

}  // namespace

cv::Mat FelzenszwalbSegmentation(const cv::Mat& bgr, double sigma, double k, int min_size,
                                 int* num_components) {
  CHECK(!bgr.empty());
  CHECK_EQ(bgr.type(), CV_8UC3);
  CHECK(num_components != nullptr);
  const int rows = bgr.rows;
  const int cols = bgr.cols;
  const int64_t num_pixels = static_cast<int64_t>(rows) * cols;
  CHECK_LT(num_pixels * 4, int64_t{1} << 32) << "image too large for the edge encoding";

  cv::Mat smooth;
  bgr.convertTo(smooth, CV_32F);
  if (sigma > 0) {
    cv::GaussianBlur(smooth, smooth, cv::Size(0, 0), sigma, sigma, cv::BORDER_REPLICATE);
  }

  // Edges of the 8-connected grid, each once: right, down, down-right, up-right. An edge is
  // (weight bits << 32 | pixel * 4 + direction); weights are non-negative floats, so their bit
  // patterns sort like the weights.
  const int offsets[4] = {1, cols, cols + 1, 1 - cols};
  std::vector<uint64_t> edges(static_cast<size_t>(num_pixels) * 4);
  size_t num_edges = 0;
  auto weight_key = [](const float* p, const float* q) -> uint64_t {
    const float d0 = p[0] - q[0];
    const float d1 = p[1] - q[1];
    const float d2 = p[2] - q[2];
    const float w = std::sqrt(d0 * d0 + d1 * d1 + d2 * d2);
    uint32_t bits;
    std::memcpy(&bits, &w, sizeof(bits));
    return static_cast<uint64_t>(bits) << 32;
  };
  for (int y = 0; y < rows; ++y) {
    const float* row = smooth.ptr<float>(y);
    const float* below = y + 1 < rows ? smooth.ptr<float>(y + 1) : nullptr;
    const float* above = y > 0 ? smooth.ptr<float>(y - 1) : nullptr;
    const uint64_t base = static_cast<uint64_t>(y) * cols * 4;
    for (int x = 0; x < cols; ++x) {
      const float* p = row + 3 * x;
      const uint64_t id = base + static_cast<uint64_t>(x) * 4;
      if (x + 1 < cols) edges[num_edges++] = weight_key(p, p + 3) | id;
      if (below != nullptr) edges[num_edges++] = weight_key(p, below + 3 * x) | (id + 1);
      if (below != nullptr && x + 1 < cols) {
        edges[num_edges++] = weight_key(p, below + 3 * x + 3) | (id + 2);
      }
      if (above != nullptr && x + 1 < cols) {
        edges[num_edges++] = weight_key(p, above + 3 * x + 3) | (id + 3);
      }
    }
  }
  edges.resize(num_edges);
  RadixSortByUpperWord(&edges);

  // Kruskal-like pass with the adaptive threshold Int(C) + k / |C| [Felzenszwalb04, Alg. 1].
  const int n = static_cast<int>(num_pixels);
  DisjointSets sets(n);
  std::vector<float> threshold(static_cast<size_t>(n), static_cast<float>(k));
  auto endpoints = [&offsets](uint64_t edge, int* a, int* b) {
    const uint32_t code = static_cast<uint32_t>(edge);
    *a = static_cast<int>(code >> 2);
    *b = *a + offsets[code & 3];
  };
  auto weight_of = [](uint64_t edge) {
    const uint32_t bits = static_cast<uint32_t>(edge >> 32);
    float w;
    std::memcpy(&w, &bits, sizeof(w));
    return w;
  };
  for (const uint64_t edge : edges) {
    int a, b;
    endpoints(edge, &a, &b);
    const int ra = sets.Find(a);
    const int rb = sets.Find(b);
    if (ra == rb) continue;
    const float w = weight_of(edge);
    if (w <= threshold[ra] && w <= threshold[rb]) {
      const int r = sets.Join(ra, rb);
      threshold[r] = w + static_cast<float>(k / sets.Size(r));
    }
  }
  // Components under min_size pixels join their neighbours along the lightest edges.
  if (min_size > 1) {
    for (const uint64_t edge : edges) {
      int a, b;
      endpoints(edge, &a, &b);
      const int ra = sets.Find(a);
      const int rb = sets.Find(b);
      if (ra != rb && (sets.Size(ra) < min_size || sets.Size(rb) < min_size)) sets.Join(ra, rb);
    }
  }

  cv::Mat labels(rows, cols, CV_32S);
  std::vector<int> new_id(static_cast<size_t>(n), -1);
  int next = 0;
  for (int y = 0; y < rows; ++y) {
    int* out = labels.ptr<int>(y);
    for (int x = 0; x < cols; ++x) {
      int& id = new_id[sets.Find(y * cols + x)];
      if (id < 0) id = next++;
      out[x] = id;
    }
  }
  *num_components = next;
  return labels;
}

namespace {

using NeighbourList = std::vector<std::pair<int, int>>;  // (region, shared length), by region

// Adds `length` to the entry of `id` in a list sorted by id, inserting it when absent.
void AddLength(NeighbourList* list, int id, int length) {
  auto it = std::lower_bound(list->begin(), list->end(), std::make_pair(id, 0));
  if (it != list->end() && it->first == id) {
    it->second += length;
  } else {
    list->insert(it, {id, length});
  }
}

void Remove(NeighbourList* list, int id) {
  auto it = std::lower_bound(list->begin(), list->end(), std::make_pair(id, 0));
  if (it != list->end() && it->first == id) list->erase(it);
}

// Regions of a partition while they are being merged. Merged regions point to the region they
// joined through `parent`; live regions are their own parent.
struct MergeState {
  std::vector<int> area;
  std::vector<cv::Vec3d> lab_sum;
  std::vector<NeighbourList> neighbours;  // live regions only
  std::vector<int> parent;
  int live = 0;

  int Find(int x) {
    while (parent[x] != x) {
      parent[x] = parent[parent[x]];
      x = parent[x];
    }
    return x;
  }

  // Merges live region `from` into live neighbour `into`, keeping boundary lengths exact.
  void MergeInto(int from, int into) {
    for (const auto& [other, length] : neighbours[from]) {
      if (other == into) continue;
      AddLength(&neighbours[into], other, length);
      Remove(&neighbours[other], from);
      AddLength(&neighbours[other], into, length);
    }
    Remove(&neighbours[into], from);
    NeighbourList().swap(neighbours[from]);
    area[into] += area[from];
    lab_sum[into] += lab_sum[from];
    parent[from] = into;
    --live;
  }

  cv::Vec3d MeanLab(int region) const { return lab_sum[region] * (1.0 / area[region]); }
};

double SquaredDistance(const cv::Vec3d& a, const cv::Vec3d& b) {
  const cv::Vec3d d = a - b;
  return d.dot(d);
}

// Seed §3.6: regions under `min_area` pixels join the neighbour they share the longest boundary
// with (ties: the larger neighbour, then the lower id), smallest region first, until none is
// left (or only one region remains).
void MergeSmallRegions(double min_area, MergeState* state) {
  using Entry = std::pair<int, int>;  // (area, region)
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> queue;
  for (int i = 0; i < static_cast<int>(state->area.size()); ++i) {
    if (state->area[i] < min_area) queue.emplace(state->area[i], i);
  }
  while (!queue.empty() && state->live > 1) {
    const auto [area, region] = queue.top();
    queue.pop();
    if (state->parent[region] != region || state->area[region] != area) continue;  // stale
    const NeighbourList& list = state->neighbours[region];
    if (list.empty()) continue;
    int best = -1;
    int best_length = -1;
    for (const auto& [other, length] : list) {
      if (length > best_length ||
          (length == best_length && state->area[other] > state->area[best])) {
        best = other;
        best_length = length;
      }
    }
    state->MergeInto(region, best);
    if (state->area[best] < min_area) queue.emplace(state->area[best], best);
  }
}

// Seed §3.6: adjacent regions of similar colour merge. Candidate pairs (mean Lab distance under
// `max_distance`) are taken in increasing distance; each merge is re-checked with the current
// means of the merged groups, so a chain of slowly changing colours does not collapse into one.
void MergeSimilarColours(double max_distance, MergeState* state) {
  const double max_squared = max_distance * max_distance;
  struct Candidate {
    double squared;
    int a;
    int b;
  };
  std::vector<Candidate> candidates;
  const int n = static_cast<int>(state->area.size());
  for (int a = 0; a < n; ++a) {
    if (state->parent[a] != a) continue;
    const cv::Vec3d mean_a = state->MeanLab(a);
    for (const auto& entry : state->neighbours[a]) {
      const int b = entry.first;
      if (b < a) continue;
      const double squared = SquaredDistance(mean_a, state->MeanLab(b));
      if (squared < max_squared) candidates.push_back({squared, a, b});
    }
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& x, const Candidate& y) {
    return std::tie(x.squared, x.a, x.b) < std::tie(y.squared, y.a, y.b);
  });
  for (const Candidate& c : candidates) {
    int ra = state->Find(c.a);
    int rb = state->Find(c.b);
    if (ra == rb) continue;
    if (SquaredDistance(state->MeanLab(ra), state->MeanLab(rb)) >= max_squared) continue;
    // The larger group (the lower id on ties) stays the representative.
    if (state->area[rb] > state->area[ra] || (state->area[rb] == state->area[ra] && rb < ra)) {
      std::swap(ra, rb);
    }
    state->area[ra] += state->area[rb];
    state->lab_sum[ra] += state->lab_sum[rb];
    state->parent[rb] = ra;
    --state->live;
  }
}

}  // namespace

SceneSegmentation ComputeSuperpixels(const WorkingImage& image, const SuperpixelOptions& options) {
  return ComputeSuperpixels(image, options, nullptr);
}

SceneSegmentation ComputeSuperpixels(const WorkingImage& image, const SuperpixelOptions& options,
                                     SuperpixelSummary* summary) {
  std::string error;
  CHECK(options.Check(&error)) << error;
  CHECK(!image.bgr.empty()) << "ComputeSuperpixels needs a working image";
  CHECK_EQ(image.bgr.type(), CV_8UC3);
  CHECK_EQ(image.lab.type(), CV_32FC3);
  CHECK(image.lab.size() == image.bgr.size());

  SuperpixelSummary stats;
  Timer timer;
  // FH's parameters are for 640x480 frames (seed §6.1.2); k / |C| and min_size are in pixels,
  // so both scale with the working area.
  const double pixels = static_cast<double>(image.bgr.total());
  const double area_factor = pixels / (640.0 * 480.0);
  const int min_size = std::max(1, static_cast<int>(std::lround(options.min_size * area_factor)));
  int num_regions = 0;
  cv::Mat labels = FelzenszwalbSegmentation(image.bgr, options.sigma, options.k * area_factor,
                                            min_size, &num_regions);
  stats.fh_regions = num_regions;
  stats.fh_ms = timer.ElapsedMs();

  timer.Restart();
  RegionGraph graph = BuildRegionGraph(labels, num_regions, image.lab);
  MergeState state;
  state.area.resize(num_regions);
  state.lab_sum.resize(num_regions);
  state.parent.resize(num_regions);
  state.neighbours = std::move(graph.neighbours);
  state.live = num_regions;
  for (int i = 0; i < num_regions; ++i) {
    const RegionStats& r = graph.regions[i];
    state.area[i] = r.area;
    // Sums from the float means lose nothing that matters at Delta E resolution.
    state.lab_sum[i] = cv::Vec3d(r.mean_lab[0], r.mean_lab[1], r.mean_lab[2]) * r.area;
    state.parent[i] = i;
  }
  MergeSmallRegions(options.min_region_fraction * pixels, &state);
  stats.after_small_merge = state.live;
  stats.small_merge_ms = timer.ElapsedMs();

  timer.Restart();
  if (options.colour_merge_distance > 0) MergeSimilarColours(options.colour_merge_distance, &state);
  std::vector<int> root(static_cast<size_t>(num_regions));
  for (int i = 0; i < num_regions; ++i) root[i] = state.Find(i);
  for (int y = 0; y < labels.rows; ++y) {
    int* row = labels.ptr<int>(y);
    for (int x = 0; x < labels.cols; ++x) row[x] = root[row[x]];
  }
  SceneSegmentation segmentation;
  const int segments = CompactLabels(&labels);
  segmentation.labels = labels;
  segmentation.classes.assign(static_cast<size_t>(segments), SegmentClass::kStructured);
  segmentation.scale = image.scale;
  stats.segments = segments;
  stats.colour_merge_ms = timer.ElapsedMs();
  if (summary != nullptr) *summary = stats;
  return segmentation;
}

}  // namespace placerec
