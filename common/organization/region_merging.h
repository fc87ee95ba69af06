// Learned region merging: an extension of the seed's between-round similar-colour merge (§3.7,
// Algorithm 2) in which a boosted classifier, trained on ground-truth objects, judges whether
// two adjacent regions belong to one object. It looks at what the colour rule looks at (mean
// CIE Lab difference) and at what the colour rule misses: texture (texton histograms), the
// contrast along the common boundary, how much boundary the two share, their sizes, heights and
// background-classifier scores. Regions merge greedily, most confident pair first, and every
// merge re-describes the merged region (appearance, background class, boundaries), so the
// decisions further up see whole parts rather than superpixels.
//
// MergeState keeps a partition with everything a pair's features need, updated exactly on
// every merge (sums of pixels, samples and boundary cracks; seed Lemma 1 for boundary lengths).
// The model file (normally models/grouping.yml.gz) is one OpenCV ml::Boost with a format version
// and the feature count; placerec-train grouping learns it.
#pragma once

#include <array>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/ml.hpp>

#include "common/organization/background.h"
#include "common/organization/boosted_forest.h"
#include "common/segmentation/segmentation.h"
#include "common/util/status.h"

namespace placerec {

// Features of a region pair (MergeState::PairFeatures); the layout is part of the model format.
// The first kMergeRelationFeatures compare the two regions (colour, texture, boundary, shape,
// background scores). The next kMergeSemanticFeatures use the structured classes' classifiers
// (background.h; zeros without them): for each of the first kMergeStructuredScores structured
// classes the smaller and the larger of the two regions' scores, the smaller and the larger
// margin of the best background score over the best structured one, and whether both regions
// take the same class under the one-per-class decision. The next kMergeBoundaryFeatures read the
// learned boundary scores (boundary.h; zeros without them), each crack's score being the mean of
// its two pixels': along the common boundary, the mean crack score and the shares of cracks
// scoring above 0 ("object boundary"), above kStrongBoundary and below kWeakBoundary; inside the
// two regions (the cracks earlier merges removed), the smaller and the larger mean crack score
// (kNoInternalBoundary for a region no merge has formed), so that a boundary can be judged
// against the edges each side already holds. The rest place the pair in appearance space: for
// each of the 20 filter-bank features, the smaller and the larger of the two regions' means. A
// model reads the leading columns it was trained on.
constexpr int kMergeRelationFeatures = 33;
constexpr int kMergeStructuredScores = 3;
constexpr int kMergeSemanticFeatures = 2 * kMergeStructuredScores + 3;
constexpr int kMergeBoundaryOffset = kMergeRelationFeatures + kMergeSemanticFeatures;
constexpr int kMergeBoundaryFeatures = 6;
constexpr float kStrongBoundary = 1.0f;
constexpr float kWeakBoundary = -1.0f;
constexpr float kNoInternalBoundary = -4.0f;
constexpr int kMergeInternalBoundary = kMergeBoundaryOffset + 4;  // the smaller, then the larger
constexpr int kMergeAppearanceOffset = kMergeBoundaryOffset + kMergeBoundaryFeatures;
constexpr int kMergeFeatures = kMergeAppearanceOffset + 2 * 20;

struct RegionMergeOptions {
  // Regions merge while the most confident pair's boosted score (> 0: "one object") exceeds
  // this; higher merges less.
  double threshold = 0.0;
  bool Check(std::string* error) const;
};

// A partition under agglomeration.
class MergeState {
 public:
  // `labels` CV_32S ids 0..num_regions-1 covering the image; `lab` the working image's CIE Lab
  // (CV_32FC3); `appearance` RegionAppearance rows of the regions (k + 1 + kAppearanceExtras
  // columns) computed on the texton grid of `texton_stride`; `feature_inv_std` the textons'
  // per-feature scale (TextonModel::inv_std, 1 x 20); `classifier` decides the background class
  // of every (merged) region (with `one_per_class`, BackgroundClassifier::Decide's rival is
  // the best structured score); `boundary_scores`, when not empty, the learned boundary scores
  // of the pixels on the cracks of `labels` (BoundaryModel::ScoreMap, CV_32F, labels' size).
  MergeState(const cv::Mat& labels, int num_regions, const cv::Mat& lab, const cv::Mat& appearance,
             int texton_stride, const cv::Mat& feature_inv_std,
             const BackgroundClassifier& classifier, double background_threshold,
             bool one_per_class = false, const cv::Mat& boundary_scores = cv::Mat());

  int capacity() const { return static_cast<int>(regions_.size()); }
  bool alive(int region) const { return regions_[region].alive; }
  // Adjacent pairs (a < b) of live regions.
  std::vector<std::pair<int, int>> Pairs() const;
  const std::map<int, int>& NeighboursOf(int region) const;  // live neighbour -> edge index
  // Writes kMergeFeatures numbers; symmetric in a and b.
  void PairFeatures(int a, int b, float* out) const;
  // Merges b into a (both live and adjacent); a survives with the union's description.
  void Merge(int a, int b);
  // The current partition: labels compacted to 0..n-1 in order of first appearance, with each
  // region's background class.
  SceneSegmentation Result() const;
  // The id every initial region now belongs to.
  int Find(int region) const;
  SegmentClass ClassOf(int region) const { return regions_[region].segment_class; }

 private:
  struct Region {
    bool alive = true;
    double area = 0;
    double sum_x = 0, sum_y = 0;
    cv::Vec3d lab_sum, lab_squares;
    int min_x = 0, min_y = 0, max_x = 0, max_y = 0;
    double perimeter = 0;
    double samples = 0;
    std::vector<float> appearance;  // RegionAppearance row
    std::array<float, kBackgroundClasses> scores{};
    std::vector<float> structured_scores;  // one per structured classifier
    // Learned boundary scores of the cracks inside the region (those of the edges merged away).
    double internal_boundary_sum = 0;
    double internal_cracks = 0;
    // From the scores (Decide): the argmax over all classes (0..4 background, 5 + structured
    // index) and the best background score minus the best structured one (0 without them).
    int best_class = 0;
    float margin = 0;
    SegmentClass segment_class = SegmentClass::kStructured;
    std::map<int, int> neighbours;  // neighbour -> index into edges_
  };
  struct Edge {
    double shared = 0;        // crack edges
    double contrast_sum = 0;  // Delta E across each crack
    double strong = 0;        // cracks with Delta E above kStrongContrast
    double wide_sum = 0;      // Delta E of the smoothed image one pixel beyond each side
    double horizontal = 0;    // cracks between vertically adjacent pixels
    // Learned boundary scores (0 without them): their sum over the cracks, and the cracks
    // scoring above 0, above kStrongBoundary and below kWeakBoundary.
    double boundary_sum = 0;
    double boundary_positive = 0;
    double boundary_strong = 0;
    double boundary_weak = 0;
  };

  void Describe(Region* region) const;
  // Sets segment_class, best_class and margin from the scores.
  void Decide(Region* region) const;

  cv::Mat labels_;
  cv::Size size_;
  int k_ = 0;  // textons
  std::vector<float> inv_std_;
  const BackgroundClassifier& classifier_;
  double background_threshold_ = 0;
  bool one_per_class_ = false;
  bool have_boundary_ = false;
  std::vector<Region> regions_;
  std::vector<Edge> edges_;
  mutable std::vector<int> parent_;
};

// One boosted classifier, or an ensemble of several whose scores are averaged (the shipped
// model averages four training variants; models/README.md).
class RegionMergeModel {
 public:
  // 1: one classifier under "boost"; 2: "members" classifiers under "member_<i>"; 3: as 2,
  // with the semantic features before the appearance-space ones; 4: as 3, with the boundary
  // features between them (versions 1 and 2 are read when they use the relational features
  // only, version 3 when it reads no appearance-space feature).
  static constexpr int kFormatVersion = 4;
  static constexpr const char* kFileName = "grouping.yml.gz";

  struct TrainingOptions {
    int weak_count = 150;
    int max_depth = 3;
    double weight_trim_rate = 0.95;
    bool Check(std::string* error) const;
  };

  RegionMergeModel() = default;
  // `features` n x d CV_32F (d <= kMergeFeatures: the leading columns of PairFeatures),
  // `labels` 1 (same object) / 0, `weights` per row.
  static RegionMergeModel Train(const cv::Mat& features, const std::vector<int>& labels,
                                const std::vector<float>& weights, const TrainingOptions& options);
  // The ensemble of every member of `models` (none empty); its score is their mean score.
  static RegionMergeModel Ensemble(const std::vector<RegionMergeModel>& models);
  // Loads DIR/grouping.yml.gz (format 1 or 2); NotFound when the file is missing.
  static StatusOr<RegionMergeModel> Load(const std::string& directory);
  Status Save(const std::string& directory) const;

  bool empty() const { return members_.empty(); }
  int members() const { return static_cast<int>(members_.size()); }
  // Columns read: the most any member reads.
  int feature_size() const;
  // Scores (> 0: one object) of feature rows (at least feature_size() columns): the mean of the
  // members' boosted sums.
  cv::Mat Scores(const cv::Mat& features) const;

 private:
  // Keeps forests_ (what Scores evaluates) in step with members_ (what Save writes).
  void AddMember(cv::Ptr<cv::ml::Boost> boost);

  std::vector<cv::Ptr<cv::ml::Boost>> members_;
  std::vector<BoostedForest> forests_;
};

// Greedy agglomeration: merges the adjacent pair with the highest score while it exceeds
// options.threshold, re-scoring the merged region's pairs after every merge. Returns the
// number of merges. `after_merge`, when given, is called with the surviving and the absorbed
// region after every merge (training records the pairs the merging meets).
int MergeRegions(const RegionMergeModel& model, const RegionMergeOptions& options,
                 MergeState* state, const std::function<void(int, int)>& after_merge = nullptr);

}  // namespace placerec
