// Pipeline steps 3-5 together (DESIGN.md; seed §3.7, Fig. 3.14): improved superpixels, their
// textons and background classes, then Perceptual Organization of the structured parts. The
// result is the SceneSegmentation objects are cut from: every pixel in exactly one segment,
// each segment sky, tree, road, grass, water or structured (an object or an object's part).
//
// The trained models (textons.yml, background*.yml*) come from a models directory: by default
// PLACEREC_MODELS when set, otherwise the source tree's models/ (DefaultModelsDir()).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "common/organization/background.h"
#include "common/organization/boundary.h"
#include "common/organization/perceptual_organization.h"
#include "common/organization/region_merging.h"
#include "common/organization/textons.h"
#include "common/segmentation/segmentation.h"
#include "common/segmentation/superpixels.h"
#include "common/util/status.h"
#include "common/util/timer.h"

namespace placerec {

// PLACEREC_MODELS when set, otherwise the models/ directory of the source tree this library was
// built from.
std::string DefaultModelsDir();

// Textons, background classifiers, the learned boundary classifier and the learned grouping
// model, loaded once and shared (read-only) by every organizer.
struct BackgroundModel {
  TextonModel textons;
  BackgroundClassifier classifier;
  BoundaryModel boundary;     // empty when the directory has no boundary.yml.gz
  RegionMergeModel grouping;  // empty when the directory has no grouping.yml.gz

  // Whether the grouping model reads the learned boundary features (region_merging.h).
  bool GroupingReadsBoundary() const {
    return !grouping.empty() && grouping.feature_size() > kMergeBoundaryOffset;
  }
};

// Loads textons.yml, the background classifiers and, when present, boundary.yml.gz and
// grouping.yml.gz from `directory` (empty: DefaultModelsDir()). A grouping model that reads
// the boundary features without a boundary model beside it is an error.
StatusOr<std::shared_ptr<const BackgroundModel>> LoadBackgroundModel(const std::string& directory);

// The defaults are the seed's method (§3.4-3.7, §6.2.1). Two uses depart from it, each in one
// named preset: recognition (ForRecognition) and object segmentation (ForSegmentation).
struct SceneOrganizerOptions {
  // The initial partition (seed §3.6, §6.1.2: sigma 0.5, k 300, min 20 at 640x480, small and
  // similar-colour merges). working_width is applied by whoever makes the WorkingImage.
  SuperpixelOptions superpixels;
  // Textons are assigned on every `texton_stride`-th pixel in x and y; region histograms count
  // those samples (1: every pixel).
  int texton_stride = 2;
  // A region is background when its best classifier's score exceeds this (0: the boosted
  // decision, seed §3.4) and, with one_per_class, every structured class's score.
  double background_threshold = 0.0;
  // The seed's one-per-class decision (§6.2.1): a region is background only when its best
  // background score also beats every structured class's classifier (when the models have
  // structured classifiers; background.h).
  bool one_per_class = true;
  // Before the decision, each superpixel's five scores become
  // (1 - w) * own + w * (boundary-length-weighted mean of its neighbours' scores), w this value
  // (0: the seed's independent per-region decision). Background classes are spatially
  // coherent, and a superpixel's histogram over a few dozen texton samples is noisy.
  // It shapes the superpixels' classes only: the learned merging decides every region it keeps
  // again from the region's own classifier scores.
  double background_smoothing = 0.0;
  // Learned region merging (region_merging.h, not in the seed) of the classified superpixels
  // before Perceptual Organization; needs grouping.yml.gz in the models directory.
  bool learned_merge = false;
  RegionMergeOptions merge;
  // Perceptual Organization of the (merged) parts (seed §3.5, §3.7).
  OrganizationOptions organization;
  // Directory with the trained models; empty: DefaultModelsDir().
  std::string models_dir;

  // Place recognition (placerec-eval run, the server): the seed's grouping, with the five-way
  // background decision at the boosted threshold (a background class need not beat the
  // structured classes). The learned merging lowers recall at 100 % precision there
  // (docs/experiments/2026-11-29-learned-merging-in-recognition.md).
  static SceneOrganizerOptions ForRecognition();
  // Object segmentation (placerec-eval segment, the trainers): the learned merging at the
  // threshold chosen on held-out validation images, then neither the seed's rounds (§3.5) nor
  // its background merge (§3.7), which lower the score after the learned merging, and the
  // one-per-class decision at -1, the best mean background recall at the same object IoU
  // (docs/experiments/2026-11-29-learned-merging.md).
  static SceneOrganizerOptions ForSegmentation();

  bool Check(std::string* error) const;
};

// What one Segment call did, with the wall-clock time of each stage in milliseconds.
struct SceneOrganizerSummary {
  int superpixels = 0;
  int background_superpixels = 0;
  int learned_merges = 0;  // merges of the learned region merging
  OrganizationSummary organization;
  // superpixels, filter_bank, textons, classifiers, boundary (when the grouping reads it),
  // merging, organization
  StageTimings timings;
};

class SceneOrganizer {
 public:
  // Loads the models named by options.models_dir.
  static StatusOr<SceneOrganizer> Create(const SceneOrganizerOptions& options);
  // Uses an already loaded model; `options` must pass Check.
  SceneOrganizer(const SceneOrganizerOptions& options,
                 std::shared_ptr<const BackgroundModel> model);

  // Segments a working image. Thread-safe. `filter_bank` (may be null) receives the image's
  // filter-bank features (Features(image)) and `textons` (may be null) their texton map on the
  // grid of options().texton_stride, both of which the segmentation computes anyway.
  SceneSegmentation Segment(const WorkingImage& image, SceneOrganizerSummary* summary = nullptr,
                            cv::Mat* filter_bank = nullptr, TextonMap* textons = nullptr) const;

  // The stages on their own, for evaluation and training.
  // 20-d filter-bank features of the working image (CV_32FC(20)).
  cv::Mat Features(const WorkingImage& image) const;
  // Region appearance (RegionAppearance rows) of `labels` (ids 0..num_regions-1, -1 ignored)
  // from features.
  cv::Mat Appearance(const cv::Mat& features, const cv::Mat& labels, int num_regions) const;
  // Superpixels classified: the initial partition with background classes, before grouping;
  // optionally with the filter-bank features, the superpixels' RegionAppearance rows and the
  // texton map they were counted from.
  SceneSegmentation ClassifiedSuperpixels(const WorkingImage& image, cv::Mat* features = nullptr,
                                          StageTimings* timings = nullptr,
                                          cv::Mat* appearance = nullptr,
                                          TextonMap* textons = nullptr) const;
  // The learned boundary scores on the cracks of `parts` (BoundaryModel::ScoreMap) from the
  // filter-bank features; an empty matrix when the grouping model does not read them.
  cv::Mat BoundaryScores(const SceneSegmentation& parts, const cv::Mat& features) const;
  // The learned region merging of classified superpixels (`appearance` their RegionAppearance
  // rows, `boundary` their BoundaryScores); returns the merged partition with re-decided
  // classes.
  SceneSegmentation MergeParts(const SceneSegmentation& parts, const cv::Mat& appearance,
                               const cv::Mat& lab, const cv::Mat& boundary,
                               int* merges = nullptr) const;

  const SceneOrganizerOptions& options() const { return options_; }
  const BackgroundModel& model() const { return *model_; }

 private:
  SceneOrganizerOptions options_;
  std::shared_ptr<const BackgroundModel> model_;
  std::shared_ptr<const TextonAssigner> assigner_;
};

}  // namespace placerec
