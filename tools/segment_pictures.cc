#include "tools/segment_pictures.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "common/eval/plots.h"
#include "common/organization/background.h"

namespace placerec {
namespace {

// Colours (BGR) of the background classes in the overlays and of class ids in classes/*.png.
cv::Scalar ClassColour(SegmentClass c) {
  switch (c) {
    case SegmentClass::kSky:
      return {235, 190, 120};
    case SegmentClass::kTree:
      return {40, 120, 30};
    case SegmentClass::kRoad:
      return {128, 64, 128};
    case SegmentClass::kGrass:
      return {80, 220, 130};
    case SegmentClass::kWater:
      return {200, 90, 0};
    case SegmentClass::kStructured:
      return {0, 0, 0};
  }
  return {0, 0, 0};
}

cv::Vec3b RandomColour(int id) {
  std::mt19937 rng(static_cast<unsigned>(id) * 2654435761u + 7u);
  return cv::Vec3b(static_cast<uint8_t>(60 + rng() % 196), static_cast<uint8_t>(60 + rng() % 196),
                   static_cast<uint8_t>(60 + rng() % 196));
}

}  // namespace

// Left: the image with background classes tinted and structured segments outlined in their own
// colours. Right: the ground-truth objects in random colours (or the segments when there is no
// ground truth).
cv::Mat DrawSegmentOverlay(const cv::Mat& bgr, const cv::Mat& segments,
                           const std::vector<SegmentClass>& classes, const cv::Mat& objects) {
  cv::Mat left = bgr.clone();
  for (int y = 0; y < bgr.rows; ++y) {
    const int* s = segments.ptr<int>(y);
    cv::Vec3b* out = left.ptr<cv::Vec3b>(y);
    for (int x = 0; x < bgr.cols; ++x) {
      const SegmentClass c = classes[s[x]];
      if (IsBackground(c)) {
        const cv::Scalar tint = ClassColour(c);
        for (int k = 0; k < 3; ++k) {
          out[x][k] = static_cast<uint8_t>(0.45 * out[x][k] + 0.55 * tint[k]);
        }
      }
      const bool edge = (x + 1 < bgr.cols && s[x + 1] != s[x]) ||
                        (y + 1 < bgr.rows && segments.at<int>(y + 1, x) != s[x]);
      if (edge) out[x] = IsBackground(c) ? cv::Vec3b(255, 255, 255) : RandomColour(s[x]);
    }
  }
  cv::Mat right(bgr.size(), CV_8UC3);
  const cv::Mat& truth = objects.empty() ? segments : objects;
  for (int y = 0; y < bgr.rows; ++y) {
    const int* t = truth.ptr<int>(y);
    cv::Vec3b* out = right.ptr<cv::Vec3b>(y);
    for (int x = 0; x < bgr.cols; ++x) {
      out[x] = t[x] <= 0 && !objects.empty() ? cv::Vec3b(0, 0, 0) : RandomColour(t[x] + 1000);
    }
  }
  cv::Mat picture;
  cv::hconcat(left, right, picture);
  // Legend strip: the tint of each background class, then what the two halves show.
  constexpr int kStrip = 18;
  cv::Mat legend(kStrip, picture.cols, CV_8UC3, cv::Scalar(255, 255, 255));
  int x = 4;
  auto text = [&](const std::string& words, int* at) {
    int baseline = 0;
    const cv::Size size = cv::getTextSize(words, cv::FONT_HERSHEY_SIMPLEX, 0.38, 1, &baseline);
    cv::putText(legend, words, cv::Point(*at, kStrip - 5), cv::FONT_HERSHEY_SIMPLEX, 0.38,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    *at += size.width + 8;
  };
  for (int c = 0; c < kBackgroundClasses; ++c) {
    const SegmentClass background = BackgroundClassOf(c);
    cv::rectangle(legend, cv::Rect(x, 4, 10, 10), ClassColour(background), cv::FILLED);
    x += 13;
    text(SegmentClassName(background), &x);
  }
  text("| outlined: objects", &x);
  x = std::max(x, bgr.cols + 4);
  text(objects.empty() ? "right: segments" : "right: ground-truth objects", &x);
  cv::vconcat(picture, legend, picture);
  return picture;
}

// OUT/summary.png: the mean object IoU over every scored object and per class (most objects
// first), the segmentation under test beside the best superpixel setting when it was scored.
Status WriteSegmentSummaryChart(const nlohmann::json& report, const std::string& method,
                                const std::string& path) {
  const nlohmann::json& scored = report["perceptual_organization"];
  std::vector<std::pair<int, std::string>> classes;
  for (auto it = scored["classes"].begin(); it != scored["classes"].end(); ++it) {
    classes.emplace_back(it.value()["objects"].get<int>(), it.key());
  }
  std::stable_sort(classes.begin(), classes.end(),
                   [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<std::string> groups = {"all (" + std::to_string(scored["objects"].get<int>()) + ")"};
  for (const auto& [objects, name] : classes) {
    groups.push_back(name + " (" + std::to_string(objects) + ")");
  }
  auto values = [&classes](const nlohmann::json& score) {
    std::vector<double> v = {score["mean_iou"].get<double>()};
    for (const auto& c : classes) {
      v.push_back(score["classes"].contains(c.second)
                      ? score["classes"][c.second]["mean_iou"].get<double>()
                      : std::nan(""));
    }
    return v;
  };
  std::vector<BarSeries> series = {{method, values(scored)}};
  if (report.contains("superpixels")) {
    const nlohmann::json& best = report["superpixels"]["best"];
    char label[96];
    std::snprintf(label, sizeof(label), "superpixels alone (best FH: k %g, min size %d)",
                  best["k_320x240"].get<double>(), best["min_size_320x240"].get<int>());
    series.push_back({label, values(best)});
  }
  std::string dataset = report["dataset"].get<std::string>();
  while (dataset.size() > 1 && dataset.back() == '/') dataset.pop_back();
  const std::string title = std::filesystem::path(dataset).filename().string() + " " +
                            report["split"].get<std::string>() + ", " +
                            std::to_string(report["scored_images"].get<int>()) +
                            " images: object IoU (seed eq. 6.2), objects in brackets";
  // Wide enough for every group's label ("building (394)") at a readable size.
  const int width = std::clamp(100 + 95 * static_cast<int>(groups.size()), 960, 4000);
  return WriteBarChartPng(path, title, "mean IoU (%)", groups, series, width, 520);
}

}  // namespace placerec
