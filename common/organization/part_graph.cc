// Perceptual Organization, the measurements (seed §3.5): boundary complexity B (eq. 3.7-3.9)
// and the part graph with its symmetry, alignment and attachment relations (eq. 3.10-3.13).
// The energy, Algorithm 1 and Algorithm 2 are in perceptual_organization.cc.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>

#include <glog/logging.h>
#include <opencv2/imgproc.hpp>

#include "common/organization/perceptual_organization.h"
#include "common/segmentation/region_graph.h"

namespace placerec {
// ---- Boundary complexity (eq. 3.7-3.9) ----

double BoundaryComplexity(const std::vector<cv::Point>& contour, int step, int window) {
  CHECK_GE(step, 1);
  CHECK_GE(window, 2);
  const int n = static_cast<int>(contour.size());
  if (n < 3) return 0.0;
  // Orientation: convex vertices turn the same way as the contour's signed area.
  double twice_area = 0;
  for (int i = 0; i < n; ++i) {
    const cv::Point& p = contour[i];
    const cv::Point& q = contour[(i + 1) % n];
    twice_area += static_cast<double>(p.x) * q.y - static_cast<double>(q.x) * p.y;
  }
  const double orientation = twice_area >= 0 ? 1.0 : -1.0;
  auto at = [&contour, n](int64_t i) -> const cv::Point& {
    return contour[static_cast<size_t>(((i % n) + n) % n)];
  };
  double sum = 0;
  std::vector<cv::Point> points(static_cast<size_t>(window) + 1);
  for (int d = 0; d < n; ++d) {
    for (int c = 0; c <= window; ++c) points[c] = at(d + static_cast<int64_t>(c) * step);
    double arc = 0;
    for (int c = 1; c <= window; ++c) arc += cv::norm(points[c] - points[c - 1]);
    if (arc <= 0) continue;
    const double chord = cv::norm(points[window] - points[0]);
    const double strength = 1.0 - chord / arc;  // A(s, k), eq. 3.8
    int notches = 0;
    for (int c = 1; c < window; ++c) {
      const cv::Point u = points[c] - points[c - 1];
      const cv::Point v = points[c + 1] - points[c];
      const double cross = static_cast<double>(u.x) * v.y - static_cast<double>(u.y) * v.x;
      if (cross * orientation < 0) ++notches;
    }
    const double frequency =
        1.0 - 2.0 * std::abs(0.5 - static_cast<double>(notches) / (window - 1));  // eq. 3.9
    sum += strength * frequency;
  }
  return sum / n;
}

double MaskBoundaryComplexity(const cv::Mat& mask, int step, int window) {
  CHECK_EQ(mask.type(), CV_8U);
  cv::Mat padded;
  cv::copyMakeBorder(mask, padded, 1, 1, 1, 1, cv::BORDER_CONSTANT, cv::Scalar(0));
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(padded, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  double weighted = 0;
  double length = 0;
  for (const auto& contour : contours) {
    weighted += BoundaryComplexity(contour, step, window) * static_cast<double>(contour.size());
    length += static_cast<double>(contour.size());
  }
  return length > 0 ? weighted / length : 0.0;
}

// ---- Part graph ----

const PartLink* PartGraph::Link(int a, int b) const {
  const auto& list = links[a];
  const auto it = std::lower_bound(list.begin(), list.end(), b,
                                   [](const PartLink& l, int id) { return l.other < id; });
  return it != list.end() && it->other == b ? &*it : nullptr;
}

double LinkStrength(const PartLink& link, int perimeter_a, int perimeter_b,
                    const OrganizationOptions& options) {
  if (link.symmetric || link.aligned) return 1.0;  // phi psi = 0
  const double ratio = static_cast<double>(link.shared) / std::max(1, perimeter_a + perimeter_b);
  const double lambda = options.beta * std::exp(-options.alpha * link.cos_omega * ratio);
  return std::exp(-lambda);
}

namespace {

// One unit crack between two 4-adjacent pixels of different parts: its two end points in
// doubled coordinates (pixel centres at even numbers).
struct Crack {
  uint64_t key;  // low id << 32 | high id
  int x0, y0, x1, y1;
};

// Ends of a common boundary: the two mutually far points of its crack end points (two sweeps
// of "farthest from").
std::pair<cv::Point2d, cv::Point2d> BoundaryEnds(const Crack* begin, const Crack* end) {
  auto farthest = [begin, end](const cv::Point2d& from) {
    double best = -1;
    cv::Point2d point = from;
    for (const Crack* c = begin; c != end; ++c) {
      for (const cv::Point2d p : {cv::Point2d(c->x0, c->y0), cv::Point2d(c->x1, c->y1)}) {
        const double d = (p.x - from.x) * (p.x - from.x) + (p.y - from.y) * (p.y - from.y);
        if (d > best) {
          best = d;
          point = p;
        }
      }
    }
    return point;
  };
  const cv::Point2d start(begin->x0, begin->y0);
  const cv::Point2d a = farthest(start);
  const cv::Point2d b = farthest(a);
  return {a * 0.5, b * 0.5};
}

// Fraction of the pixels beside the extensions of the chord a-b (beyond both ends) that belong
// to part i or j; -1 when every sample falls outside the image.
double ExtensionHits(const cv::Mat& labels, int i, int j, const cv::Point2d& a,
                     const cv::Point2d& b, double extension) {
  const cv::Point2d chord = b - a;
  const double length = std::hypot(chord.x, chord.y);
  if (length < 1e-9) return -1.0;
  const cv::Point2d dir = chord * (1.0 / length);
  const cv::Point2d normal(-dir.y, dir.x);
  int hits = 0;
  int total = 0;
  for (int end = 0; end < 2; ++end) {
    const cv::Point2d origin = end == 0 ? b : a;
    const cv::Point2d out = end == 0 ? dir : -dir;
    // Samples half a pixel apart from the end, so that axis-parallel boundaries hit pixel
    // centres on both sides.
    for (double t = 0.5; t <= extension + 1e-9; t += 1.0) {
      const cv::Point2d q = origin + out * t;
      for (const double side : {-0.5, 0.5}) {
        const cv::Point2d s = q + normal * side;
        const int x = static_cast<int>(std::floor(s.x + 0.5));
        const int y = static_cast<int>(std::floor(s.y + 0.5));
        if (x < 0 || y < 0 || x >= labels.cols || y >= labels.rows) continue;
        const int l = labels.at<int>(y, x);
        ++total;
        hits += (l == i || l == j);
      }
    }
  }
  return total > 0 ? static_cast<double>(hits) / total : -1.0;
}

}  // namespace

PartGraph BuildPartGraph(const cv::Mat& labels, int num_parts, const cv::Mat& lab,
                         const std::vector<SegmentClass>& classes,
                         const OrganizationOptions& options) {
  CHECK_EQ(labels.type(), CV_32S);
  CHECK_EQ(static_cast<int>(classes.size()), num_parts);
  const RegionGraph regions = BuildRegionGraph(labels, num_parts, lab);
  PartGraph graph;
  graph.image_size = labels.size();
  graph.parts.resize(static_cast<size_t>(num_parts));
  graph.links.resize(static_cast<size_t>(num_parts));
  for (int i = 0; i < num_parts; ++i) {
    const RegionStats& r = regions.regions[i];
    Part& p = graph.parts[i];
    p.area = r.area;
    p.perimeter = r.perimeter;
    p.centroid = r.centroid;
    p.box = r.box;
    p.mean_lab = r.mean_lab;
    p.segment_class = classes[i];
  }
  // Boundary complexity of structured parts, each from its own bounding box.
  for (int i = 0; i < num_parts; ++i) {
    Part& p = graph.parts[i];
    if (p.area == 0 || p.segment_class != SegmentClass::kStructured) continue;
    const cv::Mat crop = labels(p.box);
    cv::Mat mask;
    cv::compare(crop, cv::Scalar(i), mask, cv::CMP_EQ);
    p.complexity = MaskBoundaryComplexity(mask, options.complexity_step, options.complexity_window);
  }

  // Cracks between parts, grouped by pair.
  std::vector<Crack> cracks;
  cracks.reserve(static_cast<size_t>(labels.rows + labels.cols) * 8);
  for (int y = 0; y < labels.rows; ++y) {
    const int* row = labels.ptr<int>(y);
    const int* below = y + 1 < labels.rows ? labels.ptr<int>(y + 1) : nullptr;
    for (int x = 0; x < labels.cols; ++x) {
      const int l = row[x];
      auto key = [l](int other) {
        const int lo = std::min(l, other);
        const int hi = std::max(l, other);
        return (static_cast<uint64_t>(lo) << 32) | static_cast<uint32_t>(hi);
      };
      if (x + 1 < labels.cols && row[x + 1] != l) {
        cracks.push_back({key(row[x + 1]), 2 * x + 1, 2 * y - 1, 2 * x + 1, 2 * y + 1});
      }
      if (below != nullptr && below[x] != l) {
        cracks.push_back({key(below[x]), 2 * x - 1, 2 * y + 1, 2 * x + 1, 2 * y + 1});
      }
    }
  }
  std::stable_sort(cracks.begin(), cracks.end(),
                   [](const Crack& a, const Crack& b) { return a.key < b.key; });
  for (size_t begin = 0; begin < cracks.size();) {
    size_t end = begin;
    while (end < cracks.size() && cracks[end].key == cracks[begin].key) ++end;
    const int a = static_cast<int>(cracks[begin].key >> 32);
    const int b = static_cast<int>(cracks[begin].key & 0xffffffffu);
    const Part& pa = graph.parts[a];
    const Part& pb = graph.parts[b];
    PartLink link;
    link.shared = static_cast<int>(end - begin);
    const auto [e0, e1] = BoundaryEnds(&cracks[begin], &cracks[begin] + (end - begin));
    const cv::Point2d chord = e1 - e0;
    const double chord_length = std::hypot(chord.x, chord.y);
    const int smaller_perimeter = std::min(pa.perimeter, pb.perimeter);
    if (link.shared >= options.enclosed_fraction * smaller_perimeter) {
      link.cos_omega = 1.0;  // enclosed: not a side-by-side attachment
    } else {
      link.cos_omega = chord_length > 0 ? std::abs(chord.x) / chord_length : 1.0;
    }
    const double shorter = std::max(1, std::min(pa.box.height, pb.box.height));
    link.symmetric =
        std::abs(pa.centroid.y - pb.centroid.y) <= options.symmetry_tolerance * shorter;
    const double extension = std::max(2.0, options.alignment_extension * chord_length);
    const double hits = ExtensionHits(labels, a, b, e0, e1, extension);
    link.aligned = hits <= options.alignment_tolerance;  // -1: nothing beyond the ends
    link.strength = LinkStrength(link, pa.perimeter, pb.perimeter, options);
    link.other = b;
    graph.links[a].push_back(link);
    link.other = a;
    graph.links[b].push_back(link);
    begin = end;
  }
  for (auto& list : graph.links) {
    std::sort(list.begin(), list.end(),
              [](const PartLink& x, const PartLink& y) { return x.other < y.other; });
  }
  return graph;
}

}  // namespace placerec
