// Approximate nearest-neighbour search over the SIFT descriptors of many objects, grown by
// insertion only, so that two processes fed the same descriptors in the same order answer alike
// and no rebuild ever stalls a lookup. Two methods:
//
// - kFlann (the default): FLANN's k-d tree grown point by point and searched with a budget of
//   leaf checks (kd_tree.h: FLANN 1.9's algorithm and answers, without its per-query cost in
//   proportion to the map). FLANN's batch build shuffles its points with std::random_device
//   (answers would differ between processes); a grown tree is deterministic. Inserting is
//   cheaper than into the graph, and a reopened map loads the tree from its snapshot (below)
//   instead of growing it again; but with a fixed number of checks it finds fewer of the exact
//   nearest neighbours as the map grows.
// - kHnsw: a hierarchical navigable small-world graph (hnswlib, Malkov and Yashunin 2018): far
//   closer to exact search than the tree with the default settings, search cost growing with
//   the logarithm of the map, but inserting costs far more (a reopened map is indexed again:
//   it has no snapshot)
//   and each descriptor carries more memory (a copy of it, its links, a lock).
//
// A kFlann tree can be written to a snapshot file (SaveSnapshot) and read back when a map is
// opened (DeferInsertion, then FinishDeferred): the tree of the Adds the snapshot covers is
// loaded instead of grown again, and only later Adds are inserted, so the index is exactly the
// one insertion would have grown. A snapshot records a digest of every descriptor, owner and
// row count it covers, in order; one that does not match (stale, foreign, another format,
// damaged) is ignored and the index is grown from scratch.
//
// The descriptor matching this serves is the seed's verification step (§5.6); the comparisons
// are in docs/experiments/2026-11-22-flann-and-ransac.md and 2026-12-03-retrieval-and-scale.md,
// the snapshot's in 2026-12-03-fast-reopen.md.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "common/util/status.h"

namespace placerec {

class GrownKdTree;

enum class DescriptorSearch { kHnsw, kFlann };

struct DescriptorIndexOptions {
  DescriptorSearch method = DescriptorSearch::kFlann;
  // kFlann: leaves checked per query; more is slower and closer to exact (FLANN SearchParams).
  int checks = 32;
  // kHnsw: links per point and layer (the graph's M; 2M in the bottom layer), candidates kept
  // while inserting (ef_construction) and while searching (ef, at least the neighbours asked
  // for). More of each is slower and closer to exact.
  int hnsw_links = 16;
  int hnsw_build_candidates = 64;
  int hnsw_search_candidates = 32;

  bool Check(std::string* error) const;
};

// What FinishDeferred did with a snapshot.
struct SnapshotLoad {
  bool used = false;            // the snapshot's tree was loaded
  int64_t covered_adds = 0;     // Add calls the loaded tree covered (0 when not used)
  int64_t inserted_points = 0;  // points inserted one by one after it (all of them when unused)
  std::string message;          // what was loaded, or why the snapshot was ignored
  double load_ms = 0;           // checking and reading the snapshot, milliseconds
  double insert_ms = 0;         // inserting the points it did not cover, milliseconds
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

  // From now until FinishDeferred, Add only records the descriptors (kFlann; kHnsw inserts at
  // once as always). Search must not be called meanwhile. For opening a map: whether a snapshot
  // fits can only be judged once the descriptors it should cover are known.
  void DeferInsertion();
  // Inserts what Add recorded since DeferInsertion. When `snapshot_path` (may be empty) holds a
  // snapshot of the first n Adds of this index (the same owners, row counts and descriptors in
  // the same order, written by SaveSnapshot of kFlann), its tree is loaded and only the later
  // Adds are inserted; otherwise every point is inserted. Either way the index then answers
  // exactly as one grown by Add alone. A snapshot that cannot be used is logged with the reason.
  SnapshotLoad FinishDeferred(const std::string& snapshot_path);
  // Writes a snapshot of the whole index to `path`: to `path`.tmp, flushed to disk, then renamed
  // over `path`, so a reader sees the old snapshot or the new one, never half of one. kFlann only;
  // may run alongside Search, not alongside Add. The snapshot holds the tree only (9 bytes per
  // node, 2n - 1 nodes for n descriptors), not the descriptors. A second save while one is
  // writing `path`.tmp (another process) is refused with an error and touches nothing.
  Status SaveSnapshot(const std::string& path) const;

 private:
  struct Hnsw;
  void AddToTree(const cv::Mat& block);
  void AddToHnsw(const cv::Mat& block, size_t first_point);
  // Digest of the first `adds` blocks (owner, rows, bytes): what a snapshot covers.
  uint64_t ContentDigest(size_t adds) const;
  // Loads the tree of the snapshot at `path` if it covers a prefix of blocks_; the number of
  // blocks it covers (and `timing`, the time each step took), or the reason it cannot be used.
  StatusOr<size_t> LoadSnapshot(const std::string& path, std::string* timing);

  DescriptorIndexOptions options_;
  std::unique_ptr<GrownKdTree> tree_;  // kFlann
  std::unique_ptr<Hnsw> hnsw_;
  std::vector<cv::Mat> blocks_;  // one per kFlann Add: the descriptor memory the tree points into
  bool deferred_ = false;        // DeferInsertion: blocks_ not yet in the tree
  std::vector<int32_t> point_owner_;
  std::vector<int32_t> point_row_;
};

}  // namespace placerec
