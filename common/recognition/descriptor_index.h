// Approximate nearest-neighbour search over the SIFT descriptors of many objects with FLANN's
// k-d tree (libflann). The tree is grown by insertion only: FLANN's batch build shuffles its
// points with std::random_device, so two processes fed the same frames would answer
// differently, and a rebuild would stall every lookup for seconds on a large map. Grown trees
// are deterministic (the same additions give the same answers) and cheap to extend, at the cost
// of a little nearest-neighbour recall against a batch-built forest with the same number of
// checks. The descriptor matching this serves is the seed's verification step (§5.6); the
// comparison is in docs/experiments/2026-11-22-flann-and-ransac.md.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace placerec {

struct DescriptorIndexOptions {
  // Leaves checked per query: more is slower and closer to exact (FLANN SearchParams).
  int checks = 32;

  bool Check(std::string* error) const;
};

class DescriptorIndex {
 public:
  struct Neighbour {
    int32_t owner = -1;  // the id given to Add
    int32_t row = -1;    // row within the owner's descriptors
    float distance = 0;  // squared Euclidean
  };

  explicit DescriptorIndex(const DescriptorIndexOptions& options);
  ~DescriptorIndex();
  DescriptorIndex(const DescriptorIndex&) = delete;
  DescriptorIndex& operator=(const DescriptorIndex&) = delete;

  // Adds the rows of `descriptors` (CV_8U, 128 columns) for `owner`. The index keeps a reference
  // to the matrix (cv::Mat reference counting); the caller must not modify it afterwards.
  void Add(int32_t owner, const cv::Mat& descriptors);

  // Up to `knn` nearest neighbours of each query row, closest first. Safe to call from several
  // threads at once, but not concurrently with Add.
  void Search(const cv::Mat& queries, int knn,
              std::vector<std::vector<Neighbour>>* neighbours) const;

  size_t size() const { return point_owner_.size(); }

 private:
  struct Flann;
  DescriptorIndexOptions options_;
  std::unique_ptr<Flann> flann_;
  std::vector<cv::Mat> blocks_;  // keeps the descriptor memory FLANN points into alive
  std::vector<int32_t> point_owner_;
  std::vector<int32_t> point_row_;
};

}  // namespace placerec
