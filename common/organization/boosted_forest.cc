#include "common/organization/boosted_forest.h"

#include <glog/logging.h>

namespace placerec {

BoostedForest::BoostedForest(const cv::ml::Boost& boost) : var_count_(boost.getVarCount()) {
  const std::vector<cv::ml::DTrees::Node>& nodes = boost.getNodes();
  const std::vector<cv::ml::DTrees::Split>& splits = boost.getSplits();
  nodes_.resize(nodes.size());
  for (size_t i = 0; i < nodes.size(); ++i) {
    const cv::ml::DTrees::Node& in = nodes[i];
    Node& out = nodes_[i];
    out.value = in.value;
    if (in.split < 0) continue;
    const cv::ml::DTrees::Split& split = splits[static_cast<size_t>(in.split)];
    CHECK(split.varIdx >= 0 && split.varIdx < var_count_) << "split variable " << split.varIdx;
    out.var = split.varIdx;
    out.threshold = split.c;
    out.inversed = split.inversed;
    out.left = in.left;
    out.right = in.right;
  }
  roots_ = boost.getRoots();
}

double BoostedForest::Sum(const float* sample) const {
  double sum = 0.0;
  for (const int root : roots_) {
    int n = root;
    while (nodes_[static_cast<size_t>(n)].var >= 0) {
      const Node& node = nodes_[static_cast<size_t>(n)];
      const bool left = (sample[node.var] <= node.threshold) != node.inversed;
      n = left ? node.left : node.right;
    }
    sum += nodes_[static_cast<size_t>(n)].value;
  }
  return sum;
}

}  // namespace placerec
