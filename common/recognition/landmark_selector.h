// Landmark selection (pipeline step 7, seed §5.3 and §5.7 step 4): an object of the current
// frame that matches (at least 6 ratio-test SIFT matches) an object of the same robot's
// previous three frames is widely visible, hence a landmark. One selector per robot.
#pragma once

#include <deque>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "common/recognition/descriptor_index.h"
#include "common/recognition/object_matcher.h"

namespace placerec {

struct LandmarkSelectorOptions {
  // Previous frames of the same robot an object is compared with (seed §5.7 step 4: three).
  int history_frames = 3;
  // "At least six pairs of SIFT descriptors are matched" (seed §5.3).
  ObjectMatchingOptions matching = [] {
    ObjectMatchingOptions m;
    m.min_matches = 6;
    m.knn = 4;
    m.min_votes = 2;
    return m;
  }();
  // One frame's descriptors are few; fewer checks find their neighbours as well.
  DescriptorIndexOptions flann = [] {
    DescriptorIndexOptions f;
    f.checks = 24;
    return f;
  }();

  bool Check(std::string* error) const;
};

struct LandmarkSelection {
  // Indices of the objects that are landmarks, increasing.
  std::vector<int> landmarks;
  // Per landmark: rows of its descriptors that matched into a previous frame (sorted, unique).
  // These are the widely visible features; by default only they are stored.
  std::vector<std::vector<int>> tracked_rows;
};

class LandmarkSelector {
 public:
  explicit LandmarkSelector(const LandmarkSelectorOptions& options);

  // Which of this frame's objects (their descriptors) match the remembered frames. Does not
  // change the selector, so query-only frames can use it freely.
  LandmarkSelection Select(const std::vector<cv::Mat>& object_descriptors) const;

  // Remembers a frame's objects as the newest history frame, forgetting the oldest.
  void Remember(const std::vector<cv::Mat>& object_descriptors);

  int history_size() const { return static_cast<int>(history_.size()); }

 private:
  struct Frame {
    std::vector<cv::Mat> objects;
    std::unique_ptr<DescriptorIndex> index;
  };
  LandmarkSelectorOptions options_;
  // Shared so that copying a selector (per-robot state snapshots) is cheap.
  std::deque<std::shared_ptr<const Frame>> history_;
};

}  // namespace placerec
