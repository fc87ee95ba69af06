#include "common/organization/scene_organizer.h"

#include <utility>

#include <glog/logging.h>

#include "common/organization/filter_bank.h"
#include "common/util/paths.h"

namespace placerec {

std::string DefaultModelsDir() { return ModelsDir("", PLACEREC_MODELS_DIR); }

StatusOr<std::shared_ptr<const BackgroundModel>> LoadBackgroundModel(
    const std::string& directory) {
  const std::string dir = directory.empty() ? DefaultModelsDir() : directory;
  StatusOr<TextonModel> textons = LoadTextons(dir + "/textons.yml");
  if (!textons.ok()) return textons.status();
  StatusOr<BackgroundClassifier> classifier = BackgroundClassifier::Load(dir);
  if (!classifier.ok()) return classifier.status();
  if (classifier->feature_size() != textons->size() + 1) {
    return Status::InvalidArgument(dir + ": classifiers read " +
                                   std::to_string(classifier->feature_size()) +
                                   " features but there are " + std::to_string(textons->size()) +
                                   " textons");
  }
  auto model = std::make_shared<BackgroundModel>();
  model->textons = std::move(*textons);
  model->classifier = std::move(*classifier);
  return std::shared_ptr<const BackgroundModel>(std::move(model));
}

bool SceneOrganizerOptions::Check(std::string* error) const {
  if (!superpixels.Check(error) || !organization.Check(error)) return false;
  if (texton_stride < 1 || texton_stride > 8) {
    *error = "texton_stride must be in [1, 8], got " + std::to_string(texton_stride);
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
  return SceneOrganizer(options, std::move(*model));
}

SceneOrganizer::SceneOrganizer(const SceneOrganizerOptions& options,
                               std::shared_ptr<const BackgroundModel> model)
    : options_(options), model_(std::move(model)) {
  std::string error;
  CHECK(options_.Check(&error)) << error;
  CHECK(model_ != nullptr);
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
                                                        StageTimings* timings) const {
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
  superpixels.classes =
      model_->classifier.Classify(appearance, options_.background_threshold);
  if (timings != nullptr) timings->emplace_back("classifiers", timer.ElapsedMs());
  if (features_out != nullptr) *features_out = features;
  return superpixels;
}

SceneSegmentation SceneOrganizer::Segment(const WorkingImage& image,
                                          SceneOrganizerSummary* summary) const {
  SceneOrganizerSummary stats;
  const SceneSegmentation parts = ClassifiedSuperpixels(image, nullptr, &stats.timings);
  stats.superpixels = parts.size();
  for (const SegmentClass c : parts.classes) stats.background_superpixels += IsBackground(c);
  Timer timer;
  SceneSegmentation result = OrganizeScene(parts.labels, parts.classes, image.lab,
                                           options_.organization, &stats.organization);
  result.scale = image.scale;
  stats.timings.emplace_back("organization", timer.ElapsedMs());
  if (summary != nullptr) *summary = std::move(stats);
  return result;
}

}  // namespace placerec
