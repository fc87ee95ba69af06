// Object classes in recognition (seed Ch. 4 applied to the landmarks of §5.7, and the semantic
// landmarks of §7.2.3): every landmark a frame stores is described (§4.1, on the filter bank the
// segmentation already computed) and classified one-per-class by the shipped object classifiers
// (models/objects/all, placerec-train objects). A landmark of a movable class (a car, a person,
// an animal) can be left out of the map: it will not be there when the place is seen again.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "common/classification/object_classifier.h"
#include "common/classification/object_description.h"
#include "common/objects/objects.h"
#include "common/organization/textons.h"
#include "common/util/status.h"

namespace placerec {

struct ObjectClassOptions {
  // Classify the landmarks a frame stores. Off: landmarks are stored without a class.
  bool enabled = true;
  // Directory of the object models (objects.yml and one classifier per class, the textons in
  // its parent as textons.yml); empty: DefaultModelsDir()/objects/all.
  std::string models_dir;
  // Speed in recognition (the description of §4.1 is otherwise the one the classifiers were
  // trained on): textons are assigned on a grid of every texton_stride-th pixel in each
  // direction (the appearance and parts-layout histograms are normalised, so a grid sample
  // estimates them), and the Poisson equation is solved on at most 64 px a side instead of 128
  // (the shape numbers are scale-free; only the discretisation is coarser).
  int texton_stride = 2;
  ObjectDescriptionOptions description = [] {
    ObjectDescriptionOptions d;
    d.shape_max_side = 64;
    return d;
  }();
  // Classes of things that move or are moved (seed §7.2.3: "the vehicles may move out of a scene
  // in any moment"; "assign low weight to mobile objects like vehicles"), by class name of
  // MSRC-21 (the shipped models) and of CamVid.
  std::vector<std::string> movable_classes = {
      "car", "body",  "face",      "bicycle", "cow",   "sheep", "bird",       "cat",
      "dog", "horse", "aeroplane", "boat",    "chair", "book",  "pedestrian", "bicyclist"};
  // Leave landmarks of a movable class out of the map when their class confidence is at least
  // min_movable_confidence (seed §7.2.3; not in the seed's experiments, which store every
  // landmark).
  bool drop_movable = false;
  double min_movable_confidence = 0.5;

  bool Check(std::string* error) const;
};

// A class and how sure the classifier is of it.
struct ObjectLabel {
  std::string name;        // a class of the models; empty when not classified
  float confidence = 0.f;  // in [0, 1]
};

class ObjectClassLabeler {
 public:
  // Loads the classifiers and the textons; NotFound / InvalidArgument with what to do when they
  // are missing or do not fit each other.
  static StatusOr<std::unique_ptr<ObjectClassLabeler>> Load(const ObjectClassOptions& options);
  // Load when options.enabled; null otherwise.
  static StatusOr<std::unique_ptr<ObjectClassLabeler>> LoadIfEnabled(
      const ObjectClassOptions& options);

  // The class of `object` (its mask at the working resolution of `filter_bank`, the frame's
  // CV_32FC(20) filter bank, ComputeFilterBank). A background segment (sky, tree, road, grass,
  // water, seed §3.4) keeps the class the segmentation gave it; a structured one gets the
  // most confident of the classes that are not background (one-per-class, seed §6.2.1). The
  // confidence is 1 / (1 + exp(-2 F)) of the class's boosted sum F: Gentle AdaBoost's sum
  // estimates half the log-odds [Friedman00]. An object whose description fails (an empty mask)
  // gets no class. `textons` (may be null or empty) is the segmentation's texton map of the
  // same filter bank: where it was computed with these textons on this grid its ids are read
  // instead of assigned again (the same ids, the same class).
  ObjectLabel Classify(const cv::Mat& filter_bank, const SceneObject& object,
                       const TextonMap* textons = nullptr) const;

  // Whether the map should leave out a landmark of this label (drop_movable).
  bool LeaveOut(const ObjectLabel& label) const;

  const ObjectClassifier& classifier() const { return classifier_; }
  const ObjectClassOptions& options() const { return options_; }

 private:
  ObjectClassLabeler(const ObjectClassOptions& options, ObjectClassifier classifier,
                     const TextonModel& textons);

  ObjectClassOptions options_;
  ObjectClassifier classifier_;
  TextonAssigner textons_;
  std::vector<bool> structured_;  // per class: not a background class name
  std::vector<bool> movable_;     // per class
};

}  // namespace placerec
