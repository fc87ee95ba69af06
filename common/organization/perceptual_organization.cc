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
