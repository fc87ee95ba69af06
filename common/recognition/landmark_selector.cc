#include "common/recognition/landmark_selector.h"

#include <algorithm>

namespace placerec {

bool LandmarkSelectorOptions::Check(std::string* error) const {
  if (history_frames < 1 || history_frames > 100) {
    *error = "landmark history_frames must be in [1, 100]";
    return false;
  }
  return matching.Check(error) && flann.Check(error);
}

LandmarkSelector::LandmarkSelector(const LandmarkSelectorOptions& options) : options_(options) {}

LandmarkSelection LandmarkSelector::Select(const std::vector<cv::Mat>& object_descriptors) const {
  std::vector<std::vector<int>> tracked(object_descriptors.size());
  std::vector<bool> is_landmark(object_descriptors.size(), false);
  // Newest frame first; an object matched there is not looked up in older frames (it is a
  // landmark already, and its tracked features are those of the newest match).
  std::vector<cv::Mat> unmatched = object_descriptors;
  for (auto it = history_.rbegin(); it != history_.rend(); ++it) {
    const auto& frame = *it;
    const std::vector<ObjectPair> pairs = MatchObjects(
        unmatched, *frame->index,
        [&frame](int32_t owner) -> const cv::Mat& { return frame->objects[owner]; },
        [](int, int32_t) { return true; }, options_.matching, nullptr);
    for (const ObjectPair& pair : pairs) {
      is_landmark[pair.query_object] = true;
      for (const DescriptorMatch& m : pair.matches) tracked[pair.query_object].push_back(m.query);
    }
    bool any_left = false;
    for (size_t o = 0; o < unmatched.size(); ++o) {
      if (is_landmark[o]) unmatched[o] = cv::Mat();
      any_left = any_left || !unmatched[o].empty();
    }
    if (!any_left) break;
  }
  LandmarkSelection selection;
  for (size_t o = 0; o < object_descriptors.size(); ++o) {
    if (!is_landmark[o]) continue;
    std::vector<int>& rows = tracked[o];
    std::sort(rows.begin(), rows.end());
    rows.erase(std::unique(rows.begin(), rows.end()), rows.end());
    selection.landmarks.push_back(static_cast<int>(o));
    selection.tracked_rows.push_back(std::move(rows));
  }
  return selection;
}

void LandmarkSelector::Remember(const std::vector<cv::Mat>& object_descriptors) {
  auto frame = std::make_shared<Frame>();
  frame->objects = object_descriptors;
  frame->index = std::make_unique<DescriptorIndex>(options_.flann);
  for (size_t o = 0; o < frame->objects.size(); ++o) {
    frame->index->Add(static_cast<int32_t>(o), frame->objects[o]);
  }
  history_.push_back(std::move(frame));
  while (static_cast<int>(history_.size()) > options_.history_frames) history_.pop_front();
}

}  // namespace placerec
