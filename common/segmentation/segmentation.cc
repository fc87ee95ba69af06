#include "common/segmentation/segmentation.h"

#include <algorithm>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include <glog/logging.h>

#include "common/image/image.h"

namespace placerec {

const char* SegmentClassName(SegmentClass segment_class) {
  switch (segment_class) {
    case SegmentClass::kSky:
      return "sky";
    case SegmentClass::kTree:
      return "tree";
    case SegmentClass::kRoad:
      return "road";
    case SegmentClass::kGrass:
      return "grass";
    case SegmentClass::kWater:
      return "water";
    case SegmentClass::kStructured:
      return "structured";
  }
  return "unknown";
}

bool IsBackground(SegmentClass segment_class) {
  switch (segment_class) {
    case SegmentClass::kSky:
    case SegmentClass::kTree:
    case SegmentClass::kRoad:
    case SegmentClass::kGrass:
    case SegmentClass::kWater:
      return true;
    case SegmentClass::kStructured:
      return false;
  }
  return false;
}

bool IsKnownSegmentClass(int64_t value) {
  switch (value) {
    case static_cast<int>(SegmentClass::kSky):
    case static_cast<int>(SegmentClass::kTree):
    case static_cast<int>(SegmentClass::kRoad):
    case static_cast<int>(SegmentClass::kGrass):
    case static_cast<int>(SegmentClass::kWater):
    case static_cast<int>(SegmentClass::kStructured):
      return true;
    default:
      return false;
  }
}

WorkingImage MakeWorkingImage(const cv::Mat& bgr, int working_width) {
  CHECK(!bgr.empty()) << "MakeWorkingImage needs an image";
  CHECK_EQ(bgr.type(), CV_8UC3) << "MakeWorkingImage needs 8-bit BGR";
  WorkingImage image;
  image.bgr = LimitWidth(bgr, working_width, &image.scale);
  image.lab = ToLab(image.bgr);
  return image;
}

int SceneSegmentation::SegmentAt(float x, float y) const {
  if (labels.empty()) return -1;
  // Full-resolution pixel i covers [i - 0.5, i + 0.5); its area maps to working pixel
  // floor((i + 0.5) * scale) (what INTER_AREA averages into). The working height was rounded,
  // so up to half a working pixel past the last row or column still belongs to the image.
  const double u = (static_cast<double>(x) + 0.5) * scale;
  const double v = (static_cast<double>(y) + 0.5) * scale;
  if (!(u >= 0.0 && u < labels.cols + 0.5 && v >= 0.0 && v < labels.rows + 0.5)) return -1;
  const int col = std::min(static_cast<int>(u), labels.cols - 1);
  const int row = std::min(static_cast<int>(v), labels.rows - 1);
  return labels.at<int>(row, col);
}

int CompactLabels(cv::Mat* labels) {
  CHECK(labels != nullptr);
  CHECK_EQ(labels->type(), CV_32S) << "labels must be CV_32S";
  if (labels->empty()) return 0;
  double min_value = 0;
  double max_value = 0;
  cv::minMaxLoc(*labels, &min_value, &max_value);
  const int min_label = static_cast<int>(min_value);
  const int64_t range = static_cast<int64_t>(max_value) - min_label + 1;
  int next = 0;
  if (range <= 4 * static_cast<int64_t>(labels->total()) + 1024) {
    // Dense ids (the usual case): a lookup table.
    std::vector<int> new_id(static_cast<size_t>(range), -1);
    for (int y = 0; y < labels->rows; ++y) {
      int* row = labels->ptr<int>(y);
      for (int x = 0; x < labels->cols; ++x) {
        int& id = new_id[static_cast<size_t>(static_cast<int64_t>(row[x]) - min_label)];
        if (id < 0) id = next++;
        row[x] = id;
      }
    }
  } else {
    std::unordered_map<int, int> new_id;
    for (int y = 0; y < labels->rows; ++y) {
      int* row = labels->ptr<int>(y);
      for (int x = 0; x < labels->cols; ++x) {
        const auto inserted = new_id.emplace(row[x], next);
        if (inserted.second) ++next;
        row[x] = inserted.first->second;
      }
    }
  }
  return next;
}

}  // namespace placerec
