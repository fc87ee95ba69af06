#include "common/recognition/descriptor_index.h"

#include <algorithm>
#include <limits>

#include <flann/flann.hpp>

#include "common/features/features.h"
#include "common/util/logging.h"

namespace placerec {

struct DescriptorIndex::Flann {
  // A one-point tree: the batch build has nothing to shuffle, so it is deterministic.
  explicit Flann(const flann::Matrix<unsigned char>& first_point)
      : index(first_point, flann::KDTreeIndexParams(1)) {
    index.buildIndex();
  }
  flann::Index<flann::L2<unsigned char>> index;
};

bool DescriptorIndexOptions::Check(std::string* error) const {
  if (checks < 1) {
    *error = "index checks must be at least 1";
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
  blocks_.push_back(block);
  for (int r = 0; r < block.rows; ++r) {
    point_owner_.push_back(owner);
    point_row_.push_back(r);
  }
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

void DescriptorIndex::Search(const cv::Mat& queries, int knn,
                             std::vector<std::vector<Neighbour>>* neighbours) const {
  neighbours->assign(queries.rows, {});
  if (!flann_ || queries.empty() || knn <= 0) return;
  CHECK_EQ(queries.type(), CV_8U);
  CHECK_EQ(queries.cols, kDescriptorSize);
  const cv::Mat query_block = queries.isContinuous() ? queries : queries.clone();
  const size_t k = std::min<size_t>(knn, size());
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
