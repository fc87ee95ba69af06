#include "common/objects/objects.h"

#include <algorithm>
#include <cmath>

#include "common/util/logging.h"

namespace placerec {

bool ColourSignatureOptions::Check(std::string* error) const {
  if (bin_width <= 0 || bin_width > 1) {
    *error = "colour bin_width must be in (0, 1]";
    return false;
  }
  if (peak_fraction <= 0 || peak_fraction > 1) {
    *error = "colour peak_fraction must be in (0, 1]";
    return false;
  }
  if (min_peak_separation < 0) {
    *error = "colour min_peak_separation must be non-negative";
    return false;
  }
  if (min_pixels < 1) {
    *error = "colour min_pixels must be at least 1";
    return false;
  }
  return true;
}

bool ObjectOptions::Check(std::string* error) const {
  if (min_keypoints < 1) {
    *error = "objects min_keypoints must be at least 1";
    return false;
  }
  return colour.Check(error);
}

ColourSignature FindDominantPeaks(const std::vector<float>& histogram, double min_h,
                                  const ColourSignatureOptions& options) {
  ColourSignature signature;
  const int n = static_cast<int>(histogram.size());
  if (n == 0) return signature;
  // Light [1 2 1] smoothing so that a peak split across two bins is still one peak.
  std::vector<float> smooth(n);
  for (int i = 0; i < n; ++i) {
    const float left = histogram[std::max(0, i - 1)];
    const float right = histogram[std::min(n - 1, i + 1)];
    smooth[i] = 0.25f * left + 0.5f * histogram[i] + 0.25f * right;
  }
  const float highest = *std::max_element(smooth.begin(), smooth.end());
  if (highest <= 0) return signature;
  // Local maxima (plateaus count once, at their first bin) within peak_fraction of the highest.
  std::vector<std::pair<float, int>> peaks;
  for (int i = 0; i < n; ++i) {
    const float v = smooth[i];
    if (v < options.peak_fraction * highest) continue;
    const bool left_ok = i == 0 || smooth[i - 1] < v;
    int j = i;
    while (j + 1 < n && smooth[j + 1] == v) ++j;
    const bool right_ok = j == n - 1 || smooth[j + 1] < v;
    if (left_ok && right_ok) peaks.emplace_back(v, (i + j) / 2);
    i = j;
  }
  std::sort(peaks.begin(), peaks.end(), [](const auto& a, const auto& b) {
    return a.first > b.first || (a.first == b.first && a.second < b.second);
  });
  for (const auto& [value, bin] : peaks) {
    const float h = static_cast<float>(min_h + (bin + 0.5) * options.bin_width);
    const bool separate = std::all_of(signature.peaks.begin(), signature.peaks.end(), [&](float p) {
      return std::abs(p - h) >= options.min_peak_separation;
    });
    if (separate) signature.peaks.push_back(h);
  }
  return signature;
}

std::vector<SceneObject> ExtractObjects(const Features& features,
                                        const SceneSegmentation& segmentation, const cv::Mat& h,
                                        const cv::Mat& h_valid, double max_abs_h,
                                        const ObjectOptions& options) {
  CHECK_EQ(segmentation.labels.type(), CV_32S);
  CHECK_EQ(h.size(), segmentation.labels.size());
  CHECK_EQ(h_valid.size(), segmentation.labels.size());
  const int num_segments = segmentation.size();

  // Keypoints per segment.
  std::vector<std::vector<int>> keypoints_of(num_segments);
  for (int i = 0; i < features.size(); ++i) {
    const cv::Point2f& p = features.keypoints[i].pt;
    const int segment = segmentation.SegmentAt(p.x, p.y);
    if (segment >= 0) keypoints_of[segment].push_back(i);
  }

  // Which segments are objects, and their index in the output.
  std::vector<int> object_of(num_segments, -1);
  std::vector<SceneObject> objects;
  for (int s = 0; s < num_segments; ++s) {
    if (static_cast<int>(keypoints_of[s].size()) < options.min_keypoints) continue;
    if (IsBackground(segmentation.classes[s]) && !options.include_background) continue;
    object_of[s] = static_cast<int>(objects.size());
    SceneObject object;
    object.segment = s;
    object.segment_class = segmentation.classes[s];
    object.keypoints = std::move(keypoints_of[s]);
    objects.push_back(std::move(object));
  }
  if (objects.empty()) return objects;

  // One pass over the labels: working-resolution boxes and H histograms.
  const int bins =
      std::max(1, static_cast<int>(std::ceil(2 * max_abs_h / options.colour.bin_width)));
  std::vector<cv::Point> lo(objects.size(), cv::Point(INT32_MAX, INT32_MAX));
  std::vector<cv::Point> hi(objects.size(), cv::Point(-1, -1));
  std::vector<std::vector<float>> histograms(objects.size(), std::vector<float>(bins, 0.0f));
  std::vector<int> usable(objects.size(), 0);
  for (int y = 0; y < segmentation.labels.rows; ++y) {
    const int* label = segmentation.labels.ptr<int>(y);
    const float* hv = h.ptr<float>(y);
    const uint8_t* ok = h_valid.ptr<uint8_t>(y);
    for (int x = 0; x < segmentation.labels.cols; ++x) {
      const int o = object_of[label[x]];
      if (o < 0) continue;
      lo[o].x = std::min(lo[o].x, x);
      lo[o].y = std::min(lo[o].y, y);
      hi[o].x = std::max(hi[o].x, x);
      hi[o].y = std::max(hi[o].y, y);
      if (!ok[x]) continue;
      const int bin =
          std::clamp(static_cast<int>((hv[x] + max_abs_h) / options.colour.bin_width), 0, bins - 1);
      histograms[o][bin] += 1.0f;
      ++usable[o];
    }
  }

  const double inverse_scale = 1.0 / segmentation.scale;
  for (size_t o = 0; o < objects.size(); ++o) {
    SceneObject& object = objects[o];
    object.working_box = cv::Rect(lo[o], hi[o] + cv::Point(1, 1));
    object.mask = segmentation.labels(object.working_box) == object.segment;
    const int x0 = static_cast<int>(std::floor(lo[o].x * inverse_scale));
    const int y0 = static_cast<int>(std::floor(lo[o].y * inverse_scale));
    const int x1 = static_cast<int>(std::ceil((hi[o].x + 1) * inverse_scale));
    const int y1 = static_cast<int>(std::ceil((hi[o].y + 1) * inverse_scale));
    object.box = cv::Rect(x0, y0, x1 - x0, y1 - y0);

    object.descriptors.create(object.sift_count(), kDescriptorSize, CV_8U);
    for (int r = 0; r < object.sift_count(); ++r) {
      features.descriptors.row(object.keypoints[r]).copyTo(object.descriptors.row(r));
    }

    object.h_histogram = std::move(histograms[o]);
    if (usable[o] > 0) {
      for (float& v : object.h_histogram) v /= static_cast<float>(usable[o]);
    }
    if (usable[o] >= options.colour.min_pixels) {
      object.colour = FindDominantPeaks(object.h_histogram, -max_abs_h, options.colour);
    }
  }
  return objects;
}

}  // namespace placerec
