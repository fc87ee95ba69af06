#include "common/organization/boosted_forest.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glog/logging.h>

namespace placerec {
namespace {

int DepthOf(const std::vector<cv::ml::DTrees::Node>& nodes, int n) {
  const cv::ml::DTrees::Node& node = nodes[static_cast<size_t>(n)];
  if (node.split < 0) return 0;
  return 1 + std::max(DepthOf(nodes, node.left), DepthOf(nodes, node.right));
}

}  // namespace

int BoostedForest::Depth(const cv::ml::Boost& boost) {
  int depth = 0;
  for (const int root : boost.getRoots()) depth = std::max(depth, DepthOf(boost.getNodes(), root));
  return depth;
}

bool BoostedForest::Intact(const cv::ml::Boost& boost) {
  for (const cv::ml::DTrees::Node& node : boost.getNodes()) {
    if (!std::isfinite(node.value)) return false;
  }
  const int var_count = boost.getVarCount();
  for (const cv::ml::DTrees::Split& split : boost.getSplits()) {
    if (!std::isfinite(split.c) || split.varIdx < 0 || split.varIdx >= var_count) return false;
  }
  return true;
}

BoostedForest::BoostedForest(const cv::ml::Boost& boost) : var_count_(boost.getVarCount()) {
  const std::vector<cv::ml::DTrees::Node>& nodes = boost.getNodes();
  const std::vector<cv::ml::DTrees::Split>& splits = boost.getSplits();
  for (const int root : boost.getRoots()) {
    Tree tree;
    tree.depth = DepthOf(nodes, root);
    CHECK_LE(tree.depth, kMaxDepth) << "boosted tree of depth " << tree.depth;
    tree.first_split = static_cast<int>(vars_.size());
    tree.first_leaf = static_cast<int>(leaves_.size());
    const int internal = (1 << tree.depth) - 1;
    vars_.resize(vars_.size() + static_cast<size_t>(internal), 0);
    thresholds_.resize(thresholds_.size() + static_cast<size_t>(internal),
                       std::numeric_limits<float>::infinity());
    leaves_.resize(leaves_.size() + (static_cast<size_t>(1) << tree.depth), 0.0);
    // Places OpenCV node `n` at heap slot `slot` (level `level`); a leaf above the last level
    // fills every leaf slot below it.
    auto place = [&](auto&& self, int n, int slot, int level) -> void {
      const cv::ml::DTrees::Node& node = nodes[static_cast<size_t>(n)];
      if (level == tree.depth) {
        CHECK_LT(node.split, 0);
        leaves_[static_cast<size_t>(tree.first_leaf + slot - internal)] = node.value;
        return;
      }
      if (node.split < 0) {  // padding: both children are this leaf
        self(self, n, 2 * slot + 1, level + 1);
        self(self, n, 2 * slot + 2, level + 1);
        return;
      }
      const cv::ml::DTrees::Split& split = splits[static_cast<size_t>(node.split)];
      CHECK(split.varIdx >= 0 && split.varIdx < var_count_) << "split variable " << split.varIdx;
      vars_[static_cast<size_t>(tree.first_split + slot)] = split.varIdx;
      thresholds_[static_cast<size_t>(tree.first_split + slot)] = split.c;
      // OpenCV goes left when (value <= c) != inversed.
      const int first = split.inversed ? node.right : node.left;
      const int second = split.inversed ? node.left : node.right;
      self(self, first, 2 * slot + 1, level + 1);
      self(self, second, 2 * slot + 2, level + 1);
    };
    place(place, root, 0, 0);
    trees_.push_back(tree);
  }
}

double BoostedForest::Sum(const float* sample) const {
  double sum = 0.0;
  for (const Tree& tree : trees_) {
    const int* var = vars_.data() + tree.first_split;
    const float* threshold = thresholds_.data() + tree.first_split;
    int slot = 0;
    for (int level = 0; level < tree.depth; ++level) {
      slot = 2 * slot + 1 + static_cast<int>(!(sample[var[slot]] <= threshold[slot]));
    }
    sum += leaves_[static_cast<size_t>(tree.first_leaf + slot - ((1 << tree.depth) - 1))];
  }
  return sum;
}

void BoostedForest::Sums(const float* samples, size_t stride, int n, double* out) const {
  constexpr int kBatch = 16;
  for (int start = 0; start < n; start += kBatch) {
    const int count = std::min(kBatch, n - start);
    const float* batch = samples + static_cast<size_t>(start) * stride;
    double sums[kBatch] = {};
    for (const Tree& tree : trees_) {
      const int* var = vars_.data() + tree.first_split;
      const float* threshold = thresholds_.data() + tree.first_split;
      const double* leaves = leaves_.data() + tree.first_leaf - ((1 << tree.depth) - 1);
      int slots[kBatch] = {};
      for (int level = 0; level < tree.depth; ++level) {
        for (int i = 0; i < count; ++i) {
          const int slot = slots[i];
          slots[i] = 2 * slot + 1 +
                     static_cast<int>(
                         !(batch[static_cast<size_t>(i) * stride + var[slot]] <= threshold[slot]));
        }
      }
      for (int i = 0; i < count; ++i) sums[i] += leaves[slots[i]];
    }
    std::copy(sums, sums + count, out + start);
  }
}

}  // namespace placerec
