// Object classification, first half (seed Ch. 4, §4.1): the informative object description,
// one vector of appearance, parts layout and shape numbers per object (seed Fig. 4.1: 3181 =
// 151 + 3000 + 30 with the seed's k = 150 textons). Feature selection and the per-class
// classifiers that read it (§4.2) are not here yet.
//
//   appearance    k + 1   §4.1.1  normalised texton histogram of the object's pixels, then the
//                                 height of its centroid in the image
//   parts layout  20 k    §4.1.2  "subdivide and disorder": the bounding box cut at the centroid
//                                 into 2x2 blocks, each cut in half again (4x4), a normalised
//                                 texton histogram per block
//   shape         30      §4.1.3  the Poisson equation solved over the mask (eq. 4.1-4.2),
//                                 vertical, horizontal and concave measures (eq. 4.3-4.6), ten
//                                 weighted moments of each (eq. 4.7)
//
// Textons are those of common/organization (textons.h, the shipped models/textons.yml has the
// seed's k = 150), so the sizes follow the dictionary: k + 1 + 20 k + 30 numbers.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "common/organization/textons.h"
#include "common/util/status.h"

namespace placerec {

// Subblocks of the parts layout (seed §4.1.2: 2^2 + 2^4 = 20).
constexpr int kPartsLayoutBlocks = 20;
// Weighted moments m_pq with p + q <= 3 per measure (seed eq. 4.7).
constexpr int kShapeMomentsPerMeasure = 10;
// Three measures (vertical W_0, horizontal W_pi/2, concave W_c) of ten moments (seed §4.1.3).
constexpr int kShapeFeatureSize = 3 * kShapeMomentsPerMeasure;

// Sizes of each group for a dictionary of k textons.
inline int AppearanceSize(int k) { return k + 1; }
inline int PartsLayoutSize(int k) { return kPartsLayoutBlocks * k; }
inline int ObjectDescriptionSize(int k) {
  return AppearanceSize(k) + PartsLayoutSize(k) + kShapeFeatureSize;
}

struct ObjectDescriptionOptions {
  // The Poisson equation is solved at a working resolution: the mask's bounding box is scaled
  // down (INTER_AREA) so that its longer side is at most this many pixels (not in the seed,
  // which leaves the grid at the image's). At 128 the sparse solve has at most ~16,000 unknowns
  // and takes a few milliseconds; a frame-sized object at full resolution would take ~300,000.
  // The shape numbers do not depend on the resolution (coordinates are in units of
  // sqrt(area), Phi is normalised), only the discretisation error does.
  int shape_max_side = 128;
  // gamma of eq. 4.3-4.4: how fast the vertical and horizontal measures fall off with the
  // angle between the local orientation and the axis (seed: 3).
  double orientation_gamma = 3.0;
  // delta of eq. 4.6: slope of the logistic concave measure in the normalised Phi (seed: 4).
  double concavity_delta = 4.0;

  bool Check(std::string* error) const;
};

// The three groups of seed §4.1, each in the order documented on its function below.
struct ObjectDescription {
  std::vector<float> appearance;    // AppearanceSize(k) numbers, §4.1.1
  std::vector<float> parts_layout;  // PartsLayoutSize(k) numbers, §4.1.2
  std::vector<float> shape;         // kShapeFeatureSize numbers, §4.1.3

  // appearance, parts layout, shape: the seed's 3181-d vector (Fig. 4.1) for k = 150.
  std::vector<float> Concatenated() const;
};

// The description of the object `mask` marks in `bgr`: the filter bank and textons of the
// image (common/organization) and DescribeObjectInFeatures. `bgr` CV_8UC3; `mask` CV_8UC1 of
// the same size, non-zero on the object. An empty image, a mask of another size or type, a
// mask without object pixels or options that fail Check give kInvalidArgument.
StatusOr<ObjectDescription> DescribeObject(const cv::Mat& bgr, const cv::Mat& mask,
                                           const TextonAssigner& textons,
                                           const ObjectDescriptionOptions& options);

// The same from the image's filter bank (ComputeFilterBank(ToLab(bgr)), CV_32FC(20)), computed
// once for all the objects of a frame. Textons are assigned to the object's pixels only.
StatusOr<ObjectDescription> DescribeObjectInFeatures(const cv::Mat& features, const cv::Mat& mask,
                                                     const TextonAssigner& textons,
                                                     const ObjectDescriptionOptions& options);

// Seed §4.1.1 from a texton map: `texton_ids` CV_16U (values < k where `mask` is non-zero)
// and `mask` CV_8UC1 of the same size. k + 1 numbers: the normalised histogram of the textons
// of every mask pixel (sums to 1), then the height of the mask's centroid,
// (mean row + 0.5) / rows, 0 at the top of the image and 1 at the bottom. The seed names the
// centroid's "upper, middle or bottom area"; the continuous height is the value the
// background classifiers' 151 numbers use (RegionAppearance, textons.h), and these k + 1
// numbers are RegionAppearance's first k + 1 at texton stride 1.
StatusOr<std::vector<float>> AppearanceFeatures(const cv::Mat& texton_ids, const cv::Mat& mask,
                                                int k);

// Seed §4.1.2 ("subdivide and disorder") from a texton map (as AppearanceFeatures): 20
// normalised texton histograms of k bins, concatenated. The bounding box of the mask is cut
// through the mask's centroid into 2x2 blocks; each block is cut in half both ways, which
// gives a 4x4 grid (its lines at the centroid and half-way between it and the box's sides).
// Order: the 4 coarse blocks (top-left, top-right, bottom-left, bottom-right), then the 16
// fine blocks row by row over the 4x4 grid. A pixel belongs to the block its centre lies in
// (the right or lower one when on a line). Only mask pixels are counted (the seed's Fig. 4.3 b
// shows the object's texton map cut by the mask); a block without one is all zero.
StatusOr<std::vector<float>> PartsLayoutFeatures(const cv::Mat& texton_ids, const cv::Mat& mask,
                                                 int k);

// Solution U (CV_64F, the size of `mask`, 0 outside it) of the Poisson equation
// Delta U = -1 on the mask's pixels (CV_8UC1, non-zero inside) with U = 0 on every pixel
// outside the mask and outside the image (Dirichlet), on the pixel grid (h = 1):
// 4 U(x, y) - U(x+1, y) - U(x-1, y) - U(x, y+1) - U(x, y-1) = 1, solved with Eigen's
// SimplicialLDLT. The seed's eq. 4.1 (U the mean number of random-walk steps to the
// boundary) is 4 times this, Delta U = -4 / h^2 (eq. 4.2); the constant is taken as 1, as in
// [Gorelick05], because only then Phi = U + |grad U|^2 (eq. 4.5) is constant on a disc
// (U = (R^2 - r^2) / 4, |grad U|^2 = r^2 / 4): with the seed's factor 4 it would grow fourfold
// from a disc's centre to its rim and mark a convex shape's rim as concave.
StatusOr<cv::Mat> SolvePoisson(const cv::Mat& mask);

// The per-pixel quantities of seed §4.1.3 at the mask's own resolution, CV_64F maps of the
// mask's size, 0 outside it.
struct ShapeMaps {
  cv::Mat u;             // Poisson solution (SolvePoisson)
  cv::Mat phi;           // Phi = U + |grad U|^2 (eq. 4.5)
  cv::Mat angle;         // |alpha| in [0, pi/2]: the local orientation (below)
  cv::Mat w_vertical;    // W_0 = exp(-gamma |alpha|) (eq. 4.3), the seed's vertical measure
  cv::Mat w_horizontal;  // W_pi/2 = exp(-gamma |pi/2 - |alpha||) (eq. 4.4), horizontal measure
  cv::Mat w_concave;     // W_c = 1 / (1 + exp(-delta Phi_n)), Phi_n = Phi / max |Phi| (eq. 4.6)
};

// Derivatives are central differences of U on the pixel grid (U = 0 outside the mask). alpha
// is the angle to the x axis of the eigenvector of the Hessian of U whose eigenvalue is the
// largest in absolute value (the seed's "leading eigenvector"): across a horizontal bar U
// curves most in y, alpha = pi/2 and W_pi/2 is near 1, which is why the seed calls W_pi/2 the
// horizontal measure and W_0 the vertical one. Where the Hessian's eigenvalues are equal (a
// disc's centre) no eigenvector leads; alpha = pi/4 there, so that transposing a shape swaps
// W_0 and W_pi/2 exactly.
StatusOr<ShapeMaps> ComputeShapeMaps(const cv::Mat& mask, const ObjectDescriptionOptions& options);

// Seed §4.1.3, 30 numbers: for W_0, W_pi/2 and W_c in this order, the ten moments
// m00 m10 m01 m20 m11 m02 m30 m21 m12 m03 of eq. 4.7 over the mask's pixels at the working
// resolution (shape_max_side). The seed leaves the frame of x and y open; here x (right) and
// y (down) are relative to the mask's centroid and in units of sqrt(area), so that the
// numbers do not change when the object moves or is scaled. For p + q >= 1,
// m_pq = sum w x^p y^q / sum w as in eq. 4.7; that formula makes m00 = 1 for every object,
// so m00 holds sum w / area (the mean weight: how much of the shape is vertical, horizontal
// or concave) instead.
StatusOr<std::vector<float>> ShapeFeatures(const cv::Mat& mask,
                                           const ObjectDescriptionOptions& options);

}  // namespace placerec
