#include "common/organization/perceptual_organization.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <numeric>
#include <queue>
#include <tuple>
#include <utility>

#include <glog/logging.h>
#include <opencv2/imgproc.hpp>

#include "common/segmentation/region_graph.h"

namespace placerec {

bool OrganizationOptions::Check(std::string* error) const {
  auto finite_non_negative = [error](double value, const char* name) {
    if (!(value >= 0.0) || !std::isfinite(value)) {
      *error = std::string("organization ") + name + " must be a finite value >= 0, got " +
               std::to_string(value);
      return false;
    }
    return true;
  };
  if (!finite_non_negative(theta_complexity, "theta_complexity") ||
      !finite_non_negative(theta_cohesion, "theta_cohesion") ||
      !finite_non_negative(alpha, "alpha") || !finite_non_negative(beta, "beta") ||
      !finite_non_negative(symmetry_tolerance, "symmetry_tolerance") ||
      !finite_non_negative(alignment_extension, "alignment_extension") ||
      !finite_non_negative(round_colour_merge_distance, "round_colour_merge_distance") ||
      !finite_non_negative(background_merge_colour_distance, "background_merge_colour_distance")) {
    return false;
  }
  if (complexity_step < 1) {
    *error =
        "organization complexity_step must be at least 1, got " + std::to_string(complexity_step);
    return false;
  }
  if (complexity_window < 2) {
    *error = "organization complexity_window must be at least 2, got " +
             std::to_string(complexity_window);
    return false;
  }
  if (!(alignment_tolerance >= 0.0 && alignment_tolerance <= 1.0)) {
    *error = "organization alignment_tolerance must be in [0, 1]";
    return false;
  }
  if (!(enclosed_fraction > 0.0 && enclosed_fraction <= 1.0)) {
    *error = "organization enclosed_fraction must be in (0, 1]";
    return false;
  }
  if (max_subset < 1 || max_subset > 2) {
    *error = "organization max_subset must be 1 or 2, got " + std::to_string(max_subset);
    return false;
  }
  if (max_rounds < 0) {
    *error = "organization max_rounds must be >= 0, got " + std::to_string(max_rounds);
    return false;
  }
  return true;
}

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

// ---- Energy and Algorithm 1 ----

std::vector<double> Cohesiveness(const PartGraph& graph, int reference,
                                 const std::vector<int>& region) {
  std::vector<double> c(static_cast<size_t>(graph.size()), 0.0);
  std::vector<char> inside(static_cast<size_t>(graph.size()), 0);
  for (const int i : region) inside[i] = 1;
  CHECK(inside[reference]) << "the region must contain its reference";
  // Max-product paths: Dijkstra with products of strengths <= 1.
  using Entry = std::pair<double, int>;
  std::priority_queue<Entry> queue;
  c[reference] = 1.0;
  queue.emplace(1.0, reference);
  while (!queue.empty()) {
    const auto [value, part] = queue.top();
    queue.pop();
    if (value < c[part]) continue;
    for (const PartLink& link : graph.links[part]) {
      if (!inside[link.other]) continue;
      const double candidate = value * link.strength;
      if (candidate > c[link.other]) {
        c[link.other] = candidate;
        queue.emplace(candidate, link.other);
      }
    }
  }
  return c;
}

namespace {

// A region grown from a reference part, with its cohesiveness values, potential integral and
// boundary length kept up to date, and tentative additions evaluated exactly and undone.
class RegionGrower {
 public:
  RegionGrower(const PartGraph& graph, int reference, const OrganizationOptions& options)
      : graph_(graph),
        options_(options),
        reference_(reference),
        c_(static_cast<size_t>(graph.size()), 0.0),
        inside_(static_cast<size_t>(graph.size()), 0),
        complexity_term_(static_cast<size_t>(graph.size()), 0.0) {
    const double b_ref = graph.parts[reference].complexity;
    for (int i = 0; i < graph.size(); ++i) {
      complexity_term_[i] =
          std::exp(-options.theta_complexity * std::abs(graph.parts[i].complexity - b_ref));
    }
    inside_[reference] = 1;
    c_[reference] = 1.0;
    members_.push_back(reference);
    potential_ = Potential(reference);
    boundary_ = graph.parts[reference].perimeter;
  }

  double energy() const { return Energy(potential_, boundary_); }
  const std::vector<int>& members() const { return members_; }
  bool contains(int part) const { return inside_[part] != 0; }

  // Energy of the region with `extra` (parts outside it) added; the region is left unchanged.
  double EnergyWith(const std::vector<int>& extra) {
    double potential;
    int64_t boundary;
    Apply(extra, &potential, &boundary);
    Undo(extra);
    return Energy(potential, boundary);
  }

  void Add(const std::vector<int>& extra) {
    Apply(extra, &potential_, &boundary_);
    undo_.clear();
    for (const int u : extra) members_.push_back(u);
  }

 private:
  static double Energy(double potential, int64_t boundary) {
    return boundary > 0 ? -potential / static_cast<double>(boundary) : 0.0;
  }

  double F(int part, double c) const {
    return complexity_term_[part] * std::exp(-options_.theta_cohesion * std::abs(c - 1.0));
  }
  double Potential(int part) const { return F(part, c_[part]) * graph_.parts[part].area; }

  // Adds `extra` to the membership and cohesiveness arrays (logging old values for Undo) and
  // returns the new potential integral and boundary length.
  void Apply(const std::vector<int>& extra, double* potential, int64_t* boundary) {
    double p = potential_;
    int64_t l = boundary_;
    for (const int u : extra) {
      CHECK(!inside_[u]);
      l += graph_.parts[u].perimeter;
      for (const PartLink& link : graph_.links[u]) {
        if (inside_[link.other]) l -= 2 * link.shared;
      }
      inside_[u] = 1;
      undo_.emplace_back(u, 0.0);
    }
    // Cohesiveness of the new parts from their neighbours, then improvements spread through
    // the region (max-product relaxation; values only grow).
    using Entry = std::pair<double, int>;
    std::priority_queue<Entry> queue;
    for (const int u : extra) {
      double best = 0;
      for (const PartLink& link : graph_.links[u]) {
        if (inside_[link.other]) best = std::max(best, c_[link.other] * link.strength);
      }
      c_[u] = best;
      queue.emplace(best, u);
    }
    while (!queue.empty()) {
      const auto [value, part] = queue.top();
      queue.pop();
      if (value < c_[part]) continue;
      for (const PartLink& link : graph_.links[part]) {
        if (!inside_[link.other]) continue;
        const double candidate = value * link.strength;
        if (candidate > c_[link.other] + 1e-15) {
          undo_.emplace_back(link.other, c_[link.other]);
          c_[link.other] = candidate;
          queue.emplace(candidate, link.other);
        }
      }
    }
    // Potential: the new parts, plus the change of members whose cohesiveness grew.
    std::vector<char> counted;
    for (const int u : extra) p += Potential(u);
    for (size_t i = extra.size(); i < undo_.size(); ++i) {
      const int part = undo_[i].first;
      if (std::find(extra.begin(), extra.end(), part) != extra.end()) continue;
      // A part may be logged several times; only its first old value is its original one.
      bool first = true;
      for (size_t j = extra.size(); j < i; ++j) first = first && undo_[j].first != part;
      if (!first) continue;
      p += Potential(part) - F(part, undo_[i].second) * graph_.parts[part].area;
    }
    *potential = p;
    *boundary = l;
  }

  void Undo(const std::vector<int>& extra) {
    for (auto it = undo_.rbegin(); it != undo_.rend(); ++it) c_[it->first] = it->second;
    for (const int u : extra) inside_[u] = 0;
    undo_.clear();
  }

  const PartGraph& graph_;
  const OrganizationOptions& options_;
  const int reference_;
  std::vector<double> c_;
  std::vector<char> inside_;
  std::vector<double> complexity_term_;
  std::vector<int> members_;
  std::vector<std::pair<int, double>> undo_;  // (part, old cohesiveness)
  double potential_ = 0;
  int64_t boundary_ = 0;
};

}  // namespace

double BoundaryEnergy(const PartGraph& graph, int reference, const std::vector<int>& region,
                      const OrganizationOptions& options) {
  const std::vector<double> c = Cohesiveness(graph, reference, region);
  std::vector<char> inside(static_cast<size_t>(graph.size()), 0);
  for (const int i : region) inside[i] = 1;
  const double b_ref = graph.parts[reference].complexity;
  double potential = 0;
  int64_t boundary = 0;
  for (const int i : region) {
    const Part& p = graph.parts[i];
    const double f = std::exp(-options.theta_complexity * std::abs(p.complexity - b_ref) -
                              options.theta_cohesion * std::abs(c[i] - 1.0));
    potential += f * p.area;
    boundary += p.perimeter;
    for (const PartLink& link : graph.links[i]) {
      if (inside[link.other]) boundary -= link.shared;  // each internal pair seen twice
    }
  }
  return boundary > 0 ? -potential / static_cast<double>(boundary) : 0.0;
}

std::vector<int> DetectObject(const PartGraph& graph, int reference,
                              const std::vector<char>& available,
                              const OrganizationOptions& options) {
  CHECK_EQ(static_cast<int>(available.size()), graph.size());
  RegionGrower grower(graph, reference, options);
  std::vector<char> is_candidate(static_cast<size_t>(graph.size()), 0);
  std::vector<int> candidates;
  std::vector<int> subset;
  constexpr double kMinGain = 1e-12;
  while (true) {
    // Step 2: available neighbours of the region.
    for (const int c : candidates) is_candidate[c] = 0;
    candidates.clear();
    for (const int m : grower.members()) {
      for (const PartLink& link : graph.links[m]) {
        const int o = link.other;
        if (available[o] && !grower.contains(o) && !is_candidate[o]) {
          is_candidate[o] = 1;
          candidates.push_back(o);
        }
      }
    }
    std::sort(candidates.begin(), candidates.end());
    // Steps 3-7: the subset (one neighbour, then two connected ones) that lowers the energy
    // most.
    const double current = grower.energy();
    double best_energy = current - kMinGain;
    std::vector<int> best;
    for (const int u : candidates) {
      subset.assign(1, u);
      const double e = grower.EnergyWith(subset);
      if (e < best_energy) {
        best_energy = e;
        best = subset;
      }
    }
    if (best.empty() && options.max_subset >= 2) {
      for (const int u : candidates) {
        for (const PartLink& link : graph.links[u]) {
          const int w = link.other;
          if (w <= u || !is_candidate[w]) continue;
          subset = {u, w};
          const double e = grower.EnergyWith(subset);
          if (e < best_energy) {
            best_energy = e;
            best = subset;
          }
        }
      }
    }
    if (best.empty()) break;
    grower.Add(best);
  }
  std::vector<int> members = grower.members();
  std::sort(members.begin(), members.end());
  return members;
}

// ---- Algorithm 2 ----

namespace {

// Relabels `labels` through `group` (old id -> new id, any ints) and compacts; returns the
// classes of the new ids taken from `old_classes` of any member.
std::vector<SegmentClass> Regroup(const std::vector<int>& group,
                                  const std::vector<SegmentClass>& old_classes, cv::Mat* labels) {
  for (int y = 0; y < labels->rows; ++y) {
    int* row = labels->ptr<int>(y);
    for (int x = 0; x < labels->cols; ++x) row[x] = group[row[x]];
  }
  // CompactLabels numbers ids in order of first appearance; map old groups to new ids through
  // a representative pixel-free pass: the new id of group g is the compacted id of any pixel
  // of g, so remember one old part per group.
  std::vector<int> first_part(group.size(), -1);
  for (int i = 0; i < static_cast<int>(group.size()); ++i) {
    if (first_part[group[i]] < 0) first_part[group[i]] = i;
  }
  cv::Mat before = labels->clone();
  const int n = CompactLabels(labels);
  std::vector<SegmentClass> classes(static_cast<size_t>(n), SegmentClass::kStructured);
  for (int y = 0; y < labels->rows; ++y) {
    const int* old_row = before.ptr<int>(y);
    const int* new_row = labels->ptr<int>(y);
    for (int x = 0; x < labels->cols; ++x) {
      classes[new_row[x]] = old_classes[first_part[old_row[x]]];
    }
  }
  return classes;
}

int FindRoot(std::vector<int>* parent, int x) {
  while ((*parent)[x] != x) {
    (*parent)[x] = (*parent)[(*parent)[x]];
    x = (*parent)[x];
  }
  return x;
}

// Between rounds: adjacent structured parts of similar mean colour merge, closest pairs first,
// each merge re-checked against the current means of the two groups.
std::vector<int> SimilarColourGroups(const PartGraph& graph, double max_distance) {
  const int n = graph.size();
  std::vector<int> parent(static_cast<size_t>(n));
  std::iota(parent.begin(), parent.end(), 0);
  if (max_distance <= 0) return parent;
  std::vector<cv::Vec3d> sum(static_cast<size_t>(n));
  std::vector<double> area(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    const Part& p = graph.parts[i];
    sum[i] = cv::Vec3d(p.mean_lab[0], p.mean_lab[1], p.mean_lab[2]) * p.area;
    area[i] = p.area;
  }
  const double max_squared = max_distance * max_distance;
  std::vector<std::tuple<double, int, int>> pairs;
  for (int a = 0; a < n; ++a) {
    if (graph.parts[a].segment_class != SegmentClass::kStructured) continue;
    for (const PartLink& link : graph.links[a]) {
      const int b = link.other;
      if (b <= a || graph.parts[b].segment_class != SegmentClass::kStructured) continue;
      const cv::Vec3d d = cv::Vec3d(graph.parts[a].mean_lab) - cv::Vec3d(graph.parts[b].mean_lab);
      const double squared = d.dot(d);
      if (squared < max_squared) pairs.emplace_back(squared, a, b);
    }
  }
  std::sort(pairs.begin(), pairs.end());
  for (const auto& [squared, a, b] : pairs) {
    int ra = FindRoot(&parent, a);
    int rb = FindRoot(&parent, b);
    if (ra == rb) continue;
    const cv::Vec3d d = sum[ra] * (1.0 / area[ra]) - sum[rb] * (1.0 / area[rb]);
    if (d.dot(d) >= max_squared) continue;
    if (area[rb] > area[ra] || (area[rb] == area[ra] && rb < ra)) std::swap(ra, rb);
    parent[rb] = ra;
    sum[ra] += sum[rb];
    area[ra] += area[rb];
  }
  for (int i = 0; i < n; ++i) parent[i] = FindRoot(&parent, i);
  return parent;
}

// One round of Algorithm 2 (steps 3-9): the group (reference part id) of every part;
// background parts keep their own id. Returns whether any group has more than one part.
bool GroupRound(const PartGraph& graph, const OrganizationOptions& options,
                std::vector<int>* group) {
  const int n = graph.size();
  group->assign(static_cast<size_t>(n), -1);
  std::vector<char> available(static_cast<size_t>(n), 0);
  int unknown = 0;
  for (int i = 0; i < n; ++i) {
    if (graph.parts[i].segment_class != SegmentClass::kStructured || graph.parts[i].area == 0) {
      (*group)[i] = i;
    } else {
      available[i] = 1;
      ++unknown;
    }
  }
  // Outer regions, lowest in the image first ("from the ground plane up to the sky").
  using Entry = std::pair<double, int>;  // (centroid height, -id)
  std::priority_queue<Entry> outer;
  auto push = [&](int part) { outer.emplace(graph.parts[part].centroid.y, -part); };
  for (int i = 0; i < n; ++i) {
    if (!available[i]) continue;
    for (const PartLink& link : graph.links[i]) {
      if (graph.parts[link.other].segment_class != SegmentClass::kStructured) {
        push(i);
        break;
      }
    }
  }
  bool grouped = false;
  while (unknown > 0) {
    if (outer.empty()) {
      // No known region borders what is left: start from its lowest part.
      int lowest = -1;
      for (int i = 0; i < n; ++i) {
        if (available[i] &&
            (lowest < 0 || graph.parts[i].centroid.y > graph.parts[lowest].centroid.y)) {
          lowest = i;
        }
      }
      push(lowest);
    }
    const int v = -outer.top().second;
    outer.pop();
    if (!available[v]) continue;
    const std::vector<int> object = DetectObject(graph, v, available, options);
    grouped = grouped || object.size() > 1;
    for (const int o : object) {
      (*group)[o] = v;
      available[o] = 0;
      --unknown;
    }
    for (const int o : object) {
      for (const PartLink& link : graph.links[o]) {
        if (available[link.other]) push(link.other);
      }
    }
  }
  return grouped;
}

}  // namespace

SceneSegmentation OrganizeScene(const cv::Mat& labels, const std::vector<SegmentClass>& classes,
                                const cv::Mat& lab, const OrganizationOptions& options,
                                OrganizationSummary* summary) {
  std::string error;
  CHECK(options.Check(&error)) << error;
  CHECK_EQ(labels.type(), CV_32S);
  OrganizationSummary stats;
  cv::Mat current = labels.clone();
  std::vector<SegmentClass> current_classes = classes;
  for (int round = 0; round < options.max_rounds; ++round) {
    if (round > 0 && options.round_colour_merge_distance > 0) {
      const PartGraph graph = BuildPartGraph(current, static_cast<int>(current_classes.size()), lab,
                                             current_classes, options);
      const std::vector<int> merged =
          SimilarColourGroups(graph, options.round_colour_merge_distance);
      current_classes = Regroup(merged, current_classes, &current);
    }
    const PartGraph graph = BuildPartGraph(current, static_cast<int>(current_classes.size()), lab,
                                           current_classes, options);
    int structured = 0;
    for (const Part& p : graph.parts) structured += p.segment_class == SegmentClass::kStructured;
    stats.parts.push_back(structured);
    ++stats.rounds;
    std::vector<int> group;
    const bool grouped = GroupRound(graph, options, &group);
    current_classes = Regroup(group, current_classes, &current);
    if (!grouped) break;
  }
  int background = 0;
  for (const SegmentClass c : current_classes) background += IsBackground(c);
  stats.background_parts = background;
  if (options.merge_background && background > 1) {
    const int n = static_cast<int>(current_classes.size());
    const double max_colour = options.background_merge_colour_distance;
    const RegionGraph graph = BuildRegionGraph(current, n, max_colour > 0 ? lab : cv::Mat());
    std::vector<int> parent(static_cast<size_t>(n));
    std::iota(parent.begin(), parent.end(), 0);
    for (int a = 0; a < n; ++a) {
      if (!IsBackground(current_classes[a])) continue;
      for (const auto& [b, length] : graph.neighbours[a]) {
        if (current_classes[b] != current_classes[a]) continue;
        if (max_colour > 0 &&
            cv::norm(graph.regions[a].mean_lab - graph.regions[b].mean_lab) >= max_colour) {
          continue;
        }
        const int ra = FindRoot(&parent, a);
        const int rb = FindRoot(&parent, b);
        if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
      }
    }
    for (int i = 0; i < n; ++i) parent[i] = FindRoot(&parent, i);
    current_classes = Regroup(parent, current_classes, &current);
  }
  SceneSegmentation result;
  result.labels = current;
  result.classes = current_classes;
  stats.segments = result.size();
  if (summary != nullptr) *summary = stats;
  return result;
}

}  // namespace placerec
