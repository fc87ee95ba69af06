#include "common/pipeline/object_classes.h"

#include <algorithm>
#include <cmath>

#include "common/organization/filter_bank.h"
#include "common/organization/scene_organizer.h"
#include "common/segmentation/segmentation.h"
#include "common/util/logging.h"

namespace placerec {
namespace {

bool IsBackgroundName(const std::string& name) {
  for (SegmentClass c : {SegmentClass::kSky, SegmentClass::kTree, SegmentClass::kRoad,
                         SegmentClass::kGrass, SegmentClass::kWater}) {
    if (name == SegmentClassName(c)) return true;
  }
  return name == "mountain";  // stanford_background's background-like class (seed §6.2.1)
}

std::string ParentDirectory(const std::string& path) {
  std::string trimmed = path;
  while (trimmed.size() > 1 && trimmed.back() == '/') trimmed.pop_back();
  const size_t slash = trimmed.rfind('/');
  if (slash == std::string::npos) return ".";
  return slash == 0 ? "/" : trimmed.substr(0, slash);
}

float Confidence(float boosted_sum) {
  return static_cast<float>(1.0 / (1.0 + std::exp(-2.0 * static_cast<double>(boosted_sum))));
}

}  // namespace

bool ObjectClassOptions::Check(std::string* error) const {
  if (texton_stride < 1 || texton_stride > 8) {
    *error = "texton_stride must be in [1, 8]";
    return false;
  }
  if (!(min_movable_confidence >= 0.0 && min_movable_confidence <= 1.0)) {
    *error = "min_movable_confidence must be in [0, 1]";
    return false;
  }
  for (const std::string& name : movable_classes) {
    if (name.empty()) {
      *error = "movable class names must not be empty";
      return false;
    }
  }
  return description.Check(error);
}

ObjectClassLabeler::ObjectClassLabeler(const ObjectClassOptions& options,
                                       ObjectClassifier classifier, const TextonModel& textons)
    : options_(options), classifier_(std::move(classifier)), textons_(textons) {
  for (const std::string& name : classifier_.names()) {
    structured_.push_back(!IsBackgroundName(name));
    movable_.push_back(std::find(options_.movable_classes.begin(), options_.movable_classes.end(),
                                 name) != options_.movable_classes.end());
  }
}

StatusOr<std::unique_ptr<ObjectClassLabeler>> ObjectClassLabeler::LoadIfEnabled(
    const ObjectClassOptions& options) {
  if (!options.enabled) return std::unique_ptr<ObjectClassLabeler>();
  return Load(options);
}

StatusOr<std::unique_ptr<ObjectClassLabeler>> ObjectClassLabeler::Load(
    const ObjectClassOptions& options) {
  std::string error;
  if (!options.Check(&error)) return Status::InvalidArgument(error);
  const std::string dir =
      options.models_dir.empty() ? DefaultModelsDir() + "/objects/all" : options.models_dir;
  const std::string what =
      " (train them with placerec-train objects, point --object-models at them, or run with "
      "--object-classes off)";
  StatusOr<ObjectClassifier> classifier = ObjectClassifier::Load(dir);
  if (!classifier.ok()) {
    return Status(classifier.status().code(),
                  "object classifiers: " + classifier.status().message() + what);
  }
  const std::string textons_path = ParentDirectory(dir) + "/textons.yml";
  StatusOr<TextonModel> textons = LoadTextons(textons_path);
  if (!textons.ok()) {
    return Status(textons.status().code(),
                  "object classifiers' textons: " + textons.status().message() + what);
  }
  if (classifier->feature_size() != ObjectDescriptionSize(textons->size())) {
    return Status::InvalidArgument(dir + ": the classifiers read descriptions of " +
                                   std::to_string(classifier->feature_size()) + " numbers, but " +
                                   textons_path + " (k = " + std::to_string(textons->size()) +
                                   ") gives " +
                                   std::to_string(ObjectDescriptionSize(textons->size())) + what);
  }
  return std::unique_ptr<ObjectClassLabeler>(
      new ObjectClassLabeler(options, std::move(*classifier), *textons));
}

ObjectLabel ObjectClassLabeler::Classify(const cv::Mat& filter_bank, const SceneObject& object,
                                         const TextonMap* textons) const {
  ObjectLabel label;
  if (filter_bank.empty() || object.mask.empty()) return label;
  const cv::Rect frame(0, 0, filter_bank.cols, filter_bank.rows);
  const cv::Rect box = object.working_box & frame;
  if (box.area() == 0 || box != object.working_box) return label;
  // Textons of the object's pixels on the grid (seed §4.1.1-4.1.2 from grid samples), the shape
  // (§4.1.3) from the whole mask.
  const int stride = options_.texton_stride;
  const cv::Size grid((filter_bank.cols + stride - 1) / stride,
                      (filter_bank.rows + stride - 1) / stride);
  const bool read_map = textons != nullptr && textons->model == textons_.digest() &&
                        textons->stride == stride && textons->ids.size() == grid;
  cv::Mat ids = cv::Mat::zeros(grid, CV_16U);
  cv::Mat grid_mask = cv::Mat::zeros(grid, CV_8U);
  bool any = false;
  for (int y = box.y + (stride - box.y % stride) % stride; y < box.y + box.height; y += stride) {
    const uint8_t* m = object.mask.ptr<uint8_t>(y - box.y);
    const float* f = filter_bank.ptr<float>(y);
    for (int x = box.x + (stride - box.x % stride) % stride; x < box.x + box.width; x += stride) {
      if (m[x - box.x] == 0) continue;
      grid_mask.at<uint8_t>(y / stride, x / stride) = 255;
      ids.at<uint16_t>(y / stride, x / stride) =
          read_map ? textons->ids.at<uint16_t>(y / stride, x / stride)
                   : static_cast<uint16_t>(
                         textons_.Assign(f + static_cast<size_t>(x) * kTextonFeatureSize));
      any = true;
    }
  }
  if (!any) return label;
  const int k = textons_.size();
  StatusOr<std::vector<float>> appearance = AppearanceFeatures(ids, grid_mask, k);
  StatusOr<std::vector<float>> parts = PartsLayoutFeatures(ids, grid_mask, k);
  StatusOr<std::vector<float>> shape = ShapeFeatures(object.mask, options_.description);
  if (!appearance.ok() || !parts.ok() || !shape.ok()) return label;
  std::vector<float> values = std::move(*appearance);
  values.insert(values.end(), parts->begin(), parts->end());
  values.insert(values.end(), shape->begin(), shape->end());
  const cv::Mat row(1, static_cast<int>(values.size()), CV_32F, const_cast<float*>(values.data()));
  const cv::Mat scores = classifier_.Scores(row);
  int chosen = -1;
  if (object.segment_class != SegmentClass::kStructured) {
    const std::vector<std::string>& names = classifier_.names();
    const auto it = std::find(names.begin(), names.end(), SegmentClassName(object.segment_class));
    if (it != names.end()) chosen = static_cast<int>(it - names.begin());
  }
  if (chosen < 0) {
    const bool structured = object.segment_class == SegmentClass::kStructured &&
                            std::count(structured_.begin(), structured_.end(), true) > 0;
    chosen = ObjectClassifier::Decide(scores, structured ? structured_ : std::vector<bool>())[0];
  }
  if (chosen < 0) return label;
  label.name = classifier_.names()[static_cast<size_t>(chosen)];
  label.confidence = Confidence(scores.at<float>(0, chosen));
  return label;
}

bool ObjectClassLabeler::LeaveOut(const ObjectLabel& label) const {
  if (!options_.drop_movable || label.name.empty()) return false;
  const std::vector<std::string>& names = classifier_.names();
  const auto it = std::find(names.begin(), names.end(), label.name);
  return it != names.end() && movable_[static_cast<size_t>(it - names.begin())] &&
         label.confidence >= options_.min_movable_confidence;
}

}  // namespace placerec
