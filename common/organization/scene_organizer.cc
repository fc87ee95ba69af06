#include "common/organization/scene_organizer.h"

#include <utility>

#include <glog/logging.h>

#include "common/organization/filter_bank.h"
#include "common/segmentation/region_graph.h"
#include "common/util/paths.h"

namespace placerec {

std::string DefaultModelsDir() { return ModelsDir("", PLACEREC_MODELS_DIR); }

StatusOr<std::shared_ptr<const BackgroundModel>> LoadBackgroundModel(const std::string& directory) {
  const std::string dir = directory.empty() ? DefaultModelsDir() : directory;
  StatusOr<TextonModel> textons = LoadTextons(dir + "/textons.yml");
  if (!textons.ok()) return textons.status();
  StatusOr<BackgroundClassifier> classifier = BackgroundClassifier::Load(dir);
  if (!classifier.ok()) return classifier.status();
  // The seed's k + 1 appearance numbers, or those plus the feature means and deviations.
  if (classifier->feature_size() != textons->size() + 1 &&
      classifier->feature_size() != textons->size() + 1 + kAppearanceExtras) {
    return Status::InvalidArgument(
        dir + ": classifiers read " + std::to_string(classifier->feature_size()) +
        " features but there are " + std::to_string(textons->size()) + " textons (expected " +
        std::to_string(textons->size() + 1) + " or " +
        std::to_string(textons->size() + 1 + kAppearanceExtras) + ")");
  }
  auto model = std::make_shared<BackgroundModel>();
  model->textons = std::move(*textons);
  model->classifier = std::move(*classifier);
  StatusOr<BoundaryModel> boundary = BoundaryModel::Load(dir);
  if (boundary.ok()) {
    model->boundary = std::move(*boundary);
  } else if (boundary.status().code() != StatusCode::kNotFound) {
    return boundary.status();
  }
  StatusOr<RegionMergeModel> grouping = RegionMergeModel::Load(dir);
  if (grouping.ok()) {
    model->grouping = std::move(*grouping);
  } else if (grouping.status().code() != StatusCode::kNotFound) {
    return grouping.status();
  }
  if (model->GroupingReadsBoundary() && model->boundary.empty()) {
    return Status::InvalidArgument(
        dir + ": the grouping model reads learned boundary scores but there is no " +
        BoundaryModel::kFileName + " (train it with 'placerec-train boundary --out " + dir + "')");
  }
  return std::shared_ptr<const BackgroundModel>(std::move(model));
}

namespace {

// The learned merging's threshold for the shipped grouping model: a pair merges while the
// members' mean score exceeds it. Chosen on validation images that neither the grouping model
// nor the background and boundary classifiers saw, by the mean object IoU (seed eq. 6.2) on
// stanford_background and msrc_v2 (docs/experiments/2026-12-01-learned-boundaries.md).
constexpr double kShippedGroupingThreshold = -0.5;

}  // namespace

SceneOrganizerOptions SceneOrganizerOptions::ForRecognition() {
  SceneOrganizerOptions options;
  options.one_per_class = false;
  options.merge.threshold = kShippedGroupingThreshold;  // used only with --learned-merge true
  return options;
}

SceneOrganizerOptions SceneOrganizerOptions::ForSegmentation() {
  SceneOrganizerOptions options;
  options.background_threshold = -1.0;
  options.learned_merge = true;
  options.merge.threshold = kShippedGroupingThreshold;
  options.organization.merge_background = false;
  options.organization.max_rounds = 0;
  return options;
}

bool SceneOrganizerOptions::Check(std::string* error) const {
  if (!superpixels.Check(error) || !merge.Check(error) || !organization.Check(error)) return false;
  if (texton_stride < 1 || texton_stride > 8) {
    *error = "texton_stride must be in [1, 8], got " + std::to_string(texton_stride);
    return false;
  }
  if (!(background_smoothing >= 0.0 && background_smoothing <= 1.0)) {
    *error = "background_smoothing must be in [0, 1]";
    return false;
  }
  if (!std::isfinite(background_threshold)) {
    *error = "background_threshold must be finite";
    return false;
  }
  return true;
}

StatusOr<SceneOrganizer> SceneOrganizer::Create(const SceneOrganizerOptions& options) {
  std::string error;
  if (!options.Check(&error)) return Status::InvalidArgument(error);
  StatusOr<std::shared_ptr<const BackgroundModel>> model = LoadBackgroundModel(options.models_dir);
  if (!model.ok()) return model.status();
  if (options.learned_merge && (*model)->grouping.empty()) {
    return Status::NotFound(
        "the models directory has no " + std::string(RegionMergeModel::kFileName) +
        " for the learned region merging: train it with 'placerec-train grouping' or switch the "
        "merging off (learned_merge = false, --learned-merge false)");
  }
  return SceneOrganizer(options, std::move(*model));
}

SceneOrganizer::SceneOrganizer(const SceneOrganizerOptions& options,
                               std::shared_ptr<const BackgroundModel> model)
    : options_(options), model_(std::move(model)) {
  std::string error;
  CHECK(options_.Check(&error)) << error;
  CHECK(model_ != nullptr);
  CHECK(!options_.learned_merge || !model_->grouping.empty())
      << "learned region merging needs a grouping model";
  assigner_ = std::make_shared<const TextonAssigner>(model_->textons);
}

cv::Mat SceneOrganizer::Features(const WorkingImage& image) const {
  return ComputeFilterBank(image.lab);
}

cv::Mat SceneOrganizer::Appearance(const cv::Mat& features, const cv::Mat& labels,
                                   int num_regions) const {
  const TextonMap map = ComputeTextonMap(features, *assigner_, options_.texton_stride);
  return RegionAppearance(labels, num_regions, map, features, *assigner_);
}

SceneSegmentation SceneOrganizer::ClassifiedSuperpixels(const WorkingImage& image,
                                                        cv::Mat* features_out,
                                                        StageTimings* timings,
                                                        cv::Mat* appearance_out,
                                                        TextonMap* textons_out) const {
  Timer timer;
  SceneSegmentation superpixels = ComputeSuperpixels(image, options_.superpixels);
  if (timings != nullptr) timings->emplace_back("superpixels", timer.ElapsedMs());
  timer.Restart();
  const cv::Mat features = ComputeFilterBank(image.lab);
  if (timings != nullptr) timings->emplace_back("filter_bank", timer.ElapsedMs());
  timer.Restart();
  const TextonMap map = ComputeTextonMap(features, *assigner_, options_.texton_stride);
  const cv::Mat appearance =
      RegionAppearance(superpixels.labels, superpixels.size(), map, features, *assigner_);
  if (timings != nullptr) timings->emplace_back("textons", timer.ElapsedMs());
  timer.Restart();
  cv::Mat scores = model_->classifier.Scores(appearance);
  if (options_.background_smoothing > 0 && scores.rows > 1) {
    const RegionGraph graph = BuildRegionGraph(superpixels.labels, superpixels.size(), cv::Mat());
    cv::Mat smoothed(scores.size(), CV_32F);
    const double w = options_.background_smoothing;
    for (int r = 0; r < scores.rows; ++r) {
      double neighbour[kBackgroundClasses] = {};
      double length = 0;
      for (const auto& [other, shared] : graph.neighbours[r]) {
        for (int c = 0; c < kBackgroundClasses; ++c) {
          neighbour[c] += shared * static_cast<double>(scores.at<float>(other, c));
        }
        length += shared;
      }
      for (int c = 0; c < kBackgroundClasses; ++c) {
        const double own = scores.at<float>(r, c);
        smoothed.at<float>(r, c) =
            static_cast<float>(length > 0 ? (1 - w) * own + w * neighbour[c] / length : own);
      }
    }
    scores = smoothed;
  }
  const std::vector<float> rivals = model_->classifier.Rivals(appearance, options_.one_per_class);
  superpixels.classes.resize(static_cast<size_t>(scores.rows));
  for (int r = 0; r < scores.rows; ++r) {
    superpixels.classes[r] = BackgroundClassifier::Decide(scores.ptr<float>(r),
                                                          options_.background_threshold, rivals[r]);
  }
  if (timings != nullptr) timings->emplace_back("classifiers", timer.ElapsedMs());
  if (features_out != nullptr) *features_out = features;
  if (appearance_out != nullptr) *appearance_out = appearance;
  if (textons_out != nullptr) *textons_out = map;
  return superpixels;
}

cv::Mat SceneOrganizer::BoundaryScores(const SceneSegmentation& parts,
                                       const cv::Mat& features) const {
  if (!model_->GroupingReadsBoundary()) return cv::Mat();
  return model_->boundary.ScoreMap(features, CrackPixels(parts.labels));
}

SceneSegmentation SceneOrganizer::MergeParts(const SceneSegmentation& parts,
                                             const cv::Mat& appearance, const cv::Mat& lab,
                                             const cv::Mat& boundary, int* merges) const {
  MergeState state(parts.labels, parts.size(), lab, appearance, options_.texton_stride,
                   model_->textons.inv_std, model_->classifier, options_.background_threshold,
                   options_.one_per_class, boundary);
  const int count = MergeRegions(model_->grouping, options_.merge, &state);
  if (merges != nullptr) *merges = count;
  SceneSegmentation merged = state.Result();
  merged.scale = parts.scale;
  return merged;
}

SceneSegmentation SceneOrganizer::Segment(const WorkingImage& image, SceneOrganizerSummary* summary,
                                          cv::Mat* filter_bank, TextonMap* textons) const {
  SceneOrganizerSummary stats;
  cv::Mat appearance;
  cv::Mat features;
  SceneSegmentation parts =
      ClassifiedSuperpixels(image, &features, &stats.timings, &appearance, textons);
  stats.superpixels = parts.size();
  for (const SegmentClass c : parts.classes) stats.background_superpixels += IsBackground(c);
  Timer timer;
  if (options_.learned_merge) {
    const cv::Mat boundary = BoundaryScores(parts, features);
    if (!boundary.empty()) {
      stats.timings.emplace_back("boundary", timer.ElapsedMs());
      timer.Restart();
    }
    parts = MergeParts(parts, appearance, image.lab, boundary, &stats.learned_merges);
    stats.timings.emplace_back("merging", timer.ElapsedMs());
    timer.Restart();
  }
  SceneSegmentation result = OrganizeScene(parts.labels, parts.classes, image.lab,
                                           options_.organization, &stats.organization);
  result.scale = image.scale;
  stats.timings.emplace_back("organization", timer.ElapsedMs());
  if (summary != nullptr) *summary = std::move(stats);
  if (filter_bank != nullptr) *filter_bank = std::move(features);
  return result;
}

}  // namespace placerec
