#include "common/pipeline/pictures.h"

#include <algorithm>
#include <cstdio>
#include <random>

#include <opencv2/imgproc.hpp>

namespace placerec {
namespace {

cv::Scalar Hue(int i) {
  static const cv::Scalar kPalette[] = {{0, 200, 255}, {255, 120, 0}, {0, 255, 0},   {255, 0, 255},
                                        {0, 120, 255}, {255, 255, 0}, {120, 0, 255}, {0, 255, 180}};
  return kPalette[i % 8];
}

cv::Mat Processed(const cv::Mat& frame, double scale) {
  if (scale == 1.0) return frame.clone();
  cv::Mat out;
  cv::resize(frame, out, cv::Size(), scale, scale, cv::INTER_AREA);
  return out;
}

}  // namespace

cv::Mat DrawMatchPicture(const cv::Mat& query, const FrameObservation& observation,
                         const cv::Mat& reference, double reference_scale, const PlaceMatch& match,
                         const std::string& caption) {
  cv::Mat left = Processed(query, observation.scale);
  cv::Mat right = Processed(reference, reference_scale);
  const int height = std::max(left.rows, right.rows);
  const int banner = 28;
  cv::Mat canvas(height + banner, left.cols + right.cols, CV_8UC3, cv::Scalar(30, 30, 30));
  left.copyTo(canvas(cv::Rect(0, banner, left.cols, left.rows)));
  right.copyTo(canvas(cv::Rect(left.cols, banner, right.cols, right.rows)));
  const cv::Point left_origin(0, banner);
  const cv::Point right_origin(left.cols, banner);

  for (size_t i = 0; i < match.object_pairs.size(); ++i) {
    const cv::Scalar colour = Hue(static_cast<int>(i));
    const int o = match.object_pairs[i].first;
    if (o >= 0 && o < static_cast<int>(observation.objects.size())) {
      const SceneObject& object = observation.objects[o];
      std::vector<std::vector<cv::Point>> contours;
      cv::findContours(object.mask.clone(), contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
      const double to_processed = 1.0 / observation.segmentation.scale;
      for (auto& contour : contours) {
        for (cv::Point& p : contour) {
          p = cv::Point(static_cast<int>((p.x + object.working_box.x) * to_processed),
                        static_cast<int>((p.y + object.working_box.y) * to_processed)) +
              left_origin;
        }
      }
      cv::drawContours(canvas, contours, -1, colour, 2, cv::LINE_AA);
    }
    if (i < match.landmark_boxes.size()) {
      cv::rectangle(canvas, match.landmark_boxes[i] + right_origin, colour, 2, cv::LINE_AA);
    }
  }
  for (const auto& [p, q] : match.point_pairs) {
    const cv::Point a = cv::Point(p) + left_origin;
    const cv::Point b = cv::Point(q) + right_origin;
    cv::line(canvas, a, b, cv::Scalar(0, 255, 255), 1, cv::LINE_AA);
    cv::circle(canvas, a, 2, cv::Scalar(0, 0, 255), cv::FILLED, cv::LINE_AA);
    cv::circle(canvas, b, 2, cv::Scalar(0, 0, 255), cv::FILLED, cv::LINE_AA);
  }
  cv::putText(canvas, caption, cv::Point(8, 19), cv::FONT_HERSHEY_SIMPLEX, 0.55,
              cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  return canvas;
}

cv::Mat DrawSegmentationOverlay(const cv::Mat& frame, const SceneSegmentation& segmentation) {
  cv::Mat base;
  cv::resize(frame, base, segmentation.labels.size(), 0, 0, cv::INTER_AREA);
  std::vector<cv::Vec3b> tint(segmentation.size());
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> channel(40, 255);
  for (int s = 0; s < segmentation.size(); ++s) {
    switch (segmentation.classes[s]) {
      case SegmentClass::kSky:
        tint[s] = cv::Vec3b(235, 160, 60);
        break;
      case SegmentClass::kTree:
      case SegmentClass::kGrass:
        tint[s] = cv::Vec3b(40, 200, 40);
        break;
      case SegmentClass::kRoad:
        tint[s] = cv::Vec3b(128, 128, 128);
        break;
      case SegmentClass::kWater:
        tint[s] = cv::Vec3b(200, 200, 0);
        break;
      case SegmentClass::kStructured:
        tint[s] = cv::Vec3b(channel(rng), channel(rng), channel(rng));
        break;
    }
  }
  cv::Mat out(base.size(), CV_8UC3);
  for (int y = 0; y < base.rows; ++y) {
    const int* label = segmentation.labels.ptr<int>(y);
    const cv::Vec3b* in = base.ptr<cv::Vec3b>(y);
    cv::Vec3b* o = out.ptr<cv::Vec3b>(y);
    for (int x = 0; x < base.cols; ++x) {
      const cv::Vec3b& t = tint[label[x]];
      const bool edge = (x + 1 < base.cols && label[x + 1] != label[x]) ||
                        (y + 1 < base.rows && segmentation.labels.ptr<int>(y + 1)[x] != label[x]);
      for (int c = 0; c < 3; ++c)
        o[x][c] = edge ? 255 : static_cast<uint8_t>((in[x][c] + t[c]) / 2);
    }
  }
  return out;
}

cv::Mat DrawAnalysis(const cv::Mat& frame, const FrameObservation& observation) {
  cv::Mat overlay =
      DrawSegmentationOverlay(Processed(frame, observation.scale), observation.segmentation);
  cv::resize(overlay, overlay, observation.processed_size, 0, 0, cv::INTER_NEAREST);
  std::vector<bool> in_object(observation.features.size(), false);
  for (const SceneObject& object : observation.objects) {
    for (int k : object.keypoints) in_object[k] = true;
  }
  for (int k = 0; k < observation.features.size(); ++k) {
    cv::circle(overlay, observation.features.keypoints[k].pt, 2,
               in_object[k] ? cv::Scalar(0, 0, 255) : cv::Scalar(0, 255, 255), cv::FILLED);
  }
  for (size_t i = 0; i < observation.objects.size(); ++i) {
    const SceneObject& object = observation.objects[i];
    cv::rectangle(overlay, object.box, Hue(static_cast<int>(i)), 2);
    std::string label = std::to_string(object.sift_count());
    if (object.colour.known()) {
      char h[32];
      std::snprintf(h, sizeof(h), " H%.2f%s", object.colour.peaks[0],
                    object.colour.multi_peak() ? "+" : "");
      label += h;
    }
    cv::putText(overlay, label, object.box.tl() + cv::Point(3, 14), cv::FONT_HERSHEY_SIMPLEX, 0.45,
                cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
    cv::putText(overlay, label, object.box.tl() + cv::Point(3, 14), cv::FONT_HERSHEY_SIMPLEX, 0.45,
                cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  }
  return overlay;
}

}  // namespace placerec
