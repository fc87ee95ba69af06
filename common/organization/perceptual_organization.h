// Pipeline step 5 (DESIGN.md; seed §3.5, §3.7): the Perceptual Organization model, which groups
// the parts of unknown objects into whole objects without object-specific knowledge.
//
// Parts are regions of a partition (improved superpixels in the first round). For a reference
// part a and a region R containing it, every pixel of a part i in R carries the structure
// potential (eq. 3.6)
//     f_i = exp(-theta_B |B_i - B_a| - theta_C |C_i - C_a|),   C_a = 1,
// where B is the boundary complexity (eq. 3.7-3.9) and C the cohesiveness (eq. 3.10): the best
// product of link strengths exp(-phi_ij psi_ij lambda_ij) over paths from a to i inside R, with
// phi = 0 for parts symmetric about a vertical axis (eq. 3.11), psi = 0 for aligned parts
// (eq. 3.12) and the attachment lambda_ij = beta exp(-alpha cos(omega) L(dij) / (L(di) + L(dj)))
// (eq. 3.13). The boundary energy of R is E = -sum_i f_i |i| / L(dR) (eq. 3.4). Algorithm 1
// grows R from a while adding one neighbour, or two connected neighbours, lowers E; Algorithm 2
// runs it for every structured part from the ground up, in rounds.
//
// Lengths are crack-edge counts at the working resolution (region_graph.h), image border
// included, so L(d(A u B)) = L(dA) + L(dB) - 2 L(dAB) exactly (seed Lemma 1).
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "common/segmentation/segmentation.h"

namespace placerec {

struct OrganizationOptions {
  // Weights of |B_i - B_a| and |C_i - C_a| in the structure potential (eq. 3.6; seed §3.5:
  // theta = [18, 3.5]).
  double theta_complexity = 18.0;
  double theta_cohesion = 3.5;
  // Attachment strength lambda = beta exp(-alpha cos(omega) L(dij) / (L(di) + L(dj)))
  // (eq. 3.13; seed §3.5: alpha = 20, beta = 3).
  double alpha = 20.0;
  double beta = 3.0;
  // Boundary complexity (eq. 3.7-3.9): windows of `complexity_window` steps of
  // `complexity_step` contour pixels slide along a part's outer boundary. The seed does not
  // give s and k; these values make a 10-pixel window at the working resolution.
  int complexity_step = 2;
  int complexity_window = 5;
  // Symmetry about a vertical axis (eq. 3.11): the Kronecker delta of the centroid heights
  // holds when they differ by at most this fraction of the shorter part's height.
  double symmetry_tolerance = 0.1;
  // Alignment (eq. 3.12): the line through the two ends of the common boundary is extended
  // beyond each end by this fraction of its length (at least 2 pixels); the parts are aligned
  // when at most `alignment_tolerance` of the pixels beside the extensions belong to either part.
  double alignment_extension = 0.25;
  double alignment_tolerance = 0.2;
  // A part that shares at least this fraction of its boundary with its neighbour is enclosed by
  // it; omega is then taken as 0 (the attachment is not a side-by-side one).
  double enclosed_fraction = 0.9;
  // Algorithm 1 tests subsets of up to this many connected neighbours (seed: n = 2 suffices).
  int max_subset = 2;
  // Algorithm 2 stops after this many rounds, or earlier when a round groups nothing (seed §3.7:
  // "the result of two rounds grouping is good enough in most cases"). Two rather than three:
  // on held-out stanford_background training images a third round joins neighbouring objects
  // (docs/experiments/2026-11-22-segmentation-defaults.md).
  int max_rounds = 2;
  // Between rounds, adjacent structured groups whose mean CIE Lab colours are closer than this
  // (Delta E) merge (seed §3.7); 0 disables.
  double round_colour_merge_distance = 5.0;
  // After the last round, adjacent background regions of one class merge (seed §3.7: "merge
  // all the adjacent sky objects and ground objects").
  bool merge_background = true;
  // When positive, that final merge joins two regions only when their mean CIE Lab colours are
  // closer than this (Delta E), so that a part misclassified as background does not join a whole
  // background region. 0: any two of one class (the seed, §3.7). Chosen on the first 150
  // training images of stanford_background (docs/experiments/2026-11-29-learned-merging.md).
  double background_merge_colour_distance = 15.0;

  bool Check(std::string* error) const;
};

// Boundary complexity B of a closed contour (eq. 3.7-3.9): the mean over every start point d of
// A(s, k) F(s, k), with A = 1 - chord / arc of the k steps of s points from d and F = 1 - 2
// |0.5 - n / (k - 1)| for n notches (vertices with an inner angle over 180 degrees) among the
// window's k - 1 inner vertices. 0 for a convex polygon; higher for jagged boundaries. Contours
// with fewer than 3 points have complexity 0.
double BoundaryComplexity(const std::vector<cv::Point>& contour, int step, int window);

// Boundary complexity of the part marked non-zero in `mask` (CV_8U): the length-weighted mean
// over its outer contours.
double MaskBoundaryComplexity(const cv::Mat& mask, int step, int window);

struct Part {
  int area = 0;       // pixels
  int perimeter = 0;  // crack edges, image border included
  cv::Point2d centroid;
  cv::Rect box;
  cv::Vec3f mean_lab;
  double complexity = 0.0;  // B (eq. 3.7); computed for structured parts only
  SegmentClass segment_class = SegmentClass::kStructured;
};

// The relation of a part to one neighbour.
struct PartLink {
  int other = -1;
  int shared = 0;          // common boundary length, crack edges
  double cos_omega = 0.0;  // |cos| of the angle between the common boundary's chord and the
                           // horizontal (eq. 3.13)
  bool symmetric = false;  // phi = 0 (eq. 3.11)
  bool aligned = false;    // psi = 0 (eq. 3.12)
  double strength = 0.0;   // exp(-phi psi lambda), the factor of eq. 3.10
};

struct PartGraph {
  std::vector<Part> parts;
  std::vector<std::vector<PartLink>> links;  // per part, sorted by `other`
  cv::Size image_size;

  int size() const { return static_cast<int>(parts.size()); }
  const PartLink* Link(int a, int b) const;  // null when not adjacent
};

// The graph of a partition: `labels` CV_32S with ids 0..num_parts-1, `lab` the working image's
// CIE Lab (or empty), `classes` one per part.
PartGraph BuildPartGraph(const cv::Mat& labels, int num_parts, const cv::Mat& lab,
                         const std::vector<SegmentClass>& classes,
                         const OrganizationOptions& options);

// Link strength exp(-phi psi lambda) of eq. 3.10 from the relation's fields and the two parts'
// boundary lengths.
double LinkStrength(const PartLink& link, int perimeter_a, int perimeter_b,
                    const OrganizationOptions& options);

// Cohesiveness C (eq. 3.10) of every part of `region` (which contains `reference`) spread from
// the reference through links inside the region; parts outside get 0.
std::vector<double> Cohesiveness(const PartGraph& graph, int reference,
                                 const std::vector<int>& region);

// Boundary energy E (eq. 3.4) of `region` with `reference` as the structure reference point.
double BoundaryEnergy(const PartGraph& graph, int reference, const std::vector<int>& region,
                      const OrganizationOptions& options);

// Algorithm 1: the region grown from `reference` over parts with available[i] != 0 (the
// reference itself is always in it), sorted by id.
std::vector<int> DetectObject(const PartGraph& graph, int reference,
                              const std::vector<char>& available,
                              const OrganizationOptions& options);

struct OrganizationSummary {
  int rounds = 0;            // rounds run
  std::vector<int> parts;    // structured parts at the start of each round
  int background_parts = 0;  // before the final background merge
  int segments = 0;          // in the result
};

// Algorithm 2 and the final merges: groups the structured parts of a partition (`labels`,
// CV_32S ids 0..classes.size()-1; `classes` from background identification) into objects.
// Returns every pixel in exactly one segment, each segment with its background class or
// kStructured; labels compact. `lab` is the working image's CIE Lab.
SceneSegmentation OrganizeScene(const cv::Mat& labels, const std::vector<SegmentClass>& classes,
                                const cv::Mat& lab, const OrganizationOptions& options,
                                OrganizationSummary* summary = nullptr);

}  // namespace placerec
