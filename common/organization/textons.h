// Pipeline step 4, second half (DESIGN.md; seed §3.4, §4.1.1): textons and the per-region
// appearance feature the background classifiers read.
//
// Textons are k-means centres (k = 150) of the 20-d filter-bank vectors (filter_bank.h) of
// pixels sampled from training images, learned offline (placerec-train background). Every
// dimension is first standardised with the training pixels' mean and standard deviation, so
// that texture responses weigh as much as colour in the Euclidean k-means; the centres live in
// those standardised units. A region's appearance is its normalised texton histogram plus the
// height of its centroid in the image (0 top, 1 bottom): k + 1 = 151 numbers (seed §4.1.1).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "common/organization/filter_bank.h"
#include "common/util/status.h"

namespace placerec {

struct TextonModel {
  // Version of the file format written by SaveTextons.
  static constexpr int kFormatVersion = 1;

  cv::Mat mean;     // 1 x 20 CV_32F, subtracted from a raw feature ...
  cv::Mat inv_std;  // 1 x 20 CV_32F, ... then multiplied by this per dimension
  cv::Mat centres;  // k x 20 CV_32F, in standardised units

  int size() const { return centres.rows; }
  bool empty() const { return centres.empty(); }
};

struct TextonTrainingOptions {
  int k = 150;              // textons (seed §4.1.1: k = 150)
  int max_iterations = 40;  // k-means iterations
  double epsilon = 1e-3;    // k-means stops when no centre moves more than this
  int attempts = 1;         // k-means restarts; the most compact result is kept
  uint64_t seed = 2009;     // random seed of k-means++ seeding
  // Standardise every dimension (mean 0, variance 1 on the samples) before clustering; when
  // false the raw responses are clustered (mean 0, scale 1 are stored).
  bool standardise = true;

  bool Check(std::string* error) const;
};

// k-means (k-means++ seeding, Euclidean) on `samples` (n x 20 CV_32F raw filter-bank vectors,
// n >= k) after standardising every dimension. Deterministic for a given seed.
TextonModel TrainTextons(const cv::Mat& samples, const TextonTrainingOptions& options);

// Nearest texton of one raw 20-d feature by exhaustive double-precision search (lowest index on
// ties): the reference the fast assigner is tested against.
int NearestTexton(const TextonModel& model, const float* feature);

// Fast nearest-texton assignment: ||c||^2 - 2 z.c with the centres transposed so that the
// inner loop runs over centres (vectorised by the compiler); about 3,000 multiply-adds a pixel
// for k = 150.
class TextonAssigner {
 public:
  explicit TextonAssigner(const TextonModel& model);
  // Nearest texton of a raw 20-d feature.
  int Assign(const float* feature) const;
  int size() const { return k_; }
  // Identifies the model within this process (a hash of its values): a texton map computed with
  // an assigner of the same digest holds exactly the ids this one would assign.
  uint64_t digest() const { return digest_; }

 private:
  int k_ = 0;
  int padded_ = 0;
  uint64_t digest_ = 0;
  std::vector<float> mean_;
  std::vector<float> inv_std_;
  std::vector<float> transposed_;  // 20 x padded_, centre c in column c
  std::vector<float> half_norms_;  // ||c||^2 / 2, padded with +inf
};

// Textons of a frame on a grid: ids(r, c) is the texton of pixel (r * stride, c * stride).
// A stride of 2 assigns a quarter of the pixels; region histograms use the grid samples.
struct TextonMap {
  cv::Mat ids;  // CV_16U
  int stride = 1;
  uint64_t model = 0;  // digest() of the assigner that computed it
};

// `features` is ComputeFilterBank's CV_32FC(20) image; stride >= 1.
TextonMap ComputeTextonMap(const cv::Mat& features, const TextonAssigner& assigner, int stride);

// Columns of RegionAppearance after the seed's k + 1 (histogram and height): the mean and the
// standard deviation of each of the 20 filter-bank features over the region's samples (a
// documented extension of seed §3.4: mean Lab colour and texture energy, which the histogram
// only describes through the nearest of 150 centres). Classifiers trained on the seed's
// 151 numbers read only the first k + 1 columns.
constexpr int kAppearanceExtras = 2 * kTextonFeatureSize;

// Appearance of every region of `labels` (CV_32S, ids 0..num_regions-1, the size of
// `features`): a num_regions x (k + 1 + kAppearanceExtras) CV_32F matrix, each row the region's
// texton histogram over its grid samples (summing to 1), its centroid height
// (mean row + 0.5) / rows, then the per-feature means and standard deviations over the same
// samples.
// A region without a grid sample is described by the textons of all its pixels. Labels outside
// 0..num_regions-1 (e.g. -1) are ignored; a region without pixels gets an all-zero row.
cv::Mat RegionAppearance(const cv::Mat& labels, int num_regions, const TextonMap& map,
                         const cv::Mat& features, const TextonAssigner& assigner);

Status SaveTextons(const TextonModel& model, const std::string& path);
StatusOr<TextonModel> LoadTextons(const std::string& path);

}  // namespace placerec
