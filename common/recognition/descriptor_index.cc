#include "common/recognition/descriptor_index.h"

#include <algorithm>
#include <limits>
#include <queue>

#include <hnswlib/hnswlib.h>
#include <flann/flann.hpp>

#include "common/features/features.h"
#include "common/recognition/descriptor_matching.h"
#include "common/util/logging.h"

namespace placerec {
namespace {

// Squared Euclidean distance of 128-byte descriptors for hnswlib.
class DescriptorSpace : public hnswlib::SpaceInterface<int> {
 public:
  size_t get_data_size() override { return kDescriptorSize; }
  hnswlib::DISTFUNC<int> get_dist_func() override { return &Distance; }
  void* get_dist_func_param() override { return nullptr; }

 private:
  static int Distance(const void* a, const void* b, const void*) {
    return SquaredDistance(static_cast<const uint8_t*>(a), static_cast<const uint8_t*>(b));
  }
};

// The graph's random layer assignment starts from this seed: the same insertions give the same
// graph in every process.
constexpr size_t kHnswSeed = 100;

}  // namespace

struct DescriptorIndex::Flann {
  // A one-point tree: the batch build has nothing to shuffle, so it is deterministic.
  explicit Flann(const flann::Matrix<unsigned char>& first_point)
      : index(first_point, flann::KDTreeIndexParams(1)) {
    index.buildIndex();
  }
  flann::Index<flann::L2<unsigned char>> index;
};

struct DescriptorIndex::Hnsw {
  explicit Hnsw(const DescriptorIndexOptions& options)
      : graph(&space, /*max_elements=*/1024, options.hnsw_links, options.hnsw_build_candidates,
              kHnswSeed) {
    graph.setEf(options.hnsw_search_candidates);
  }
  DescriptorSpace space;
  hnswlib::HierarchicalNSW<int> graph;
};

bool DescriptorIndexOptions::Check(std::string* error) const {
  if (checks < 1) {
    *error = "index checks must be at least 1";
    return false;
  }
  if (hnsw_links < 2 || hnsw_links > 1000 || hnsw_build_candidates < 1 ||
      hnsw_search_candidates < 1) {
    *error = "index hnsw links must be in [2, 1000] and its candidates at least 1";
    return false;
  }
  return true;
}

DescriptorIndex::DescriptorIndex(const DescriptorIndexOptions& options) : options_(options) {}

DescriptorIndex::~DescriptorIndex() = default;

void DescriptorIndex::Add(int32_t owner, const cv::Mat& descriptors) {
  if (descriptors.empty()) return;
  CHECK_EQ(descriptors.type(), CV_8U);
  CHECK_EQ(descriptors.cols, kDescriptorSize);
  cv::Mat block = descriptors.isContinuous() ? descriptors : descriptors.clone();
  const size_t first_point = point_owner_.size();
  for (int r = 0; r < block.rows; ++r) {
    point_owner_.push_back(owner);
    point_row_.push_back(r);
  }
  if (options_.method == DescriptorSearch::kHnsw) {
    AddToHnsw(block, first_point);
  } else {
    blocks_.push_back(block);
    AddToFlann(block);
  }
}

void DescriptorIndex::AddToFlann(cv::Mat block) {
  size_t first = 0;
  if (!flann_) {
    flann_ = std::make_unique<Flann>(flann::Matrix<unsigned char>(block.data, 1, kDescriptorSize));
    first = 1;
  }
  if (first < static_cast<size_t>(block.rows)) {
    // Insert only: a threshold no size reaches keeps FLANN from rebuilding.
    flann_->index.addPoints(flann::Matrix<unsigned char>(block.ptr<unsigned char>(first),
                                                         block.rows - first, kDescriptorSize),
                            std::numeric_limits<float>::max());
  }
}

void DescriptorIndex::AddToHnsw(const cv::Mat& block, size_t first_point) {
  if (!hnsw_) hnsw_ = std::make_unique<Hnsw>(options_);
  hnswlib::HierarchicalNSW<int>& graph = hnsw_->graph;
  const size_t needed = first_point + block.rows;
  if (needed > graph.max_elements_) {
    // The graph copies the descriptors; doubling keeps the copies rare.
    graph.resizeIndex(std::max(needed, 2 * graph.max_elements_));
  }
  for (int r = 0; r < block.rows; ++r) graph.addPoint(block.ptr<uint8_t>(r), first_point + r);
}

void DescriptorIndex::Search(const cv::Mat& queries, int knn,
                             std::vector<std::vector<Neighbour>>* neighbours) const {
  neighbours->assign(queries.rows, {});
  if (size() == 0 || queries.empty() || knn <= 0) return;
  CHECK_EQ(queries.type(), CV_8U);
  CHECK_EQ(queries.cols, kDescriptorSize);
  const cv::Mat query_block = queries.isContinuous() ? queries : queries.clone();
  const size_t k = std::min<size_t>(knn, size());
  if (options_.method == DescriptorSearch::kHnsw) {
    for (int q = 0; q < query_block.rows; ++q) {
      // Farthest first.
      std::priority_queue<std::pair<int, hnswlib::labeltype>> found =
          hnsw_->graph.searchKnn(query_block.ptr<uint8_t>(q), k);
      std::vector<Neighbour>& out = (*neighbours)[q];
      out.resize(found.size());
      for (size_t j = found.size(); j-- > 0; found.pop()) {
        const size_t point = found.top().second;
        out[j] = {point_owner_[point], point_row_[point], static_cast<float>(found.top().first)};
      }
    }
    return;
  }
  std::vector<size_t> index_data(query_block.rows * k);
  std::vector<float> distance_data(query_block.rows * k);
  flann::Matrix<unsigned char> query_matrix(query_block.data, query_block.rows, kDescriptorSize);
  flann::Matrix<size_t> indices(index_data.data(), query_block.rows, k);
  flann::Matrix<float> distances(distance_data.data(), query_block.rows, k);
  flann::SearchParams params(options_.checks);
  params.cores = 1;
  flann_->index.knnSearch(query_matrix, indices, distances, k, params);
  for (int q = 0; q < query_block.rows; ++q) {
    std::vector<Neighbour>& out = (*neighbours)[q];
    out.reserve(k);
    for (size_t j = 0; j < k; ++j) {
      const size_t point = indices[q][j];
      if (point >= point_owner_.size()) continue;  // FLANN fills missing neighbours with -1
      out.push_back({point_owner_[point], point_row_[point], distances[q][j]});
    }
  }
}

}  // namespace placerec
