// placerec-train objects: the object classifiers of seed Ch. 4 (§4.2 feature selection, one
// Gentle AdaBoost classifier per class, one-per-class decision; common/classification) learned
// from the ground-truth object segments of a labelled dataset's train split (seed §6.2.1: "we
// use the ground truth segments for feature extraction"), and the region accuracy that
// placerec-eval classify reports (seed Tables 6.5-6.7, Fig. 6.16).
//
// Layout of the models directory (--out): manifest.json, textons.yml (a copy of the dictionary
// the descriptions were made with) and one ObjectClassifier directory per variant of
// ObjectModelVariants(): all/ (the model), and the ablation's appearance/, appearance_parts/,
// appearance_shape/ and full/.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "common/classification/object_classifier.h"
#include "common/classification/object_description.h"
#include "common/organization/textons.h"
#include "common/training/labelled_dataset.h"
#include "common/util/status.h"

namespace placerec {

// Which ground-truth segments are described.
struct TruthSegmentOptions {
  // Objects smaller than this (image pixels) are left out: their texton histograms and shape
  // moments rest on too few pixels. The seed names no minimum.
  int min_object_pixels = 100;
  // An object's class is the majority class of its labelled pixels; objects whose labelled
  // pixels are fewer than this share of the object are left out.
  double min_labelled_fraction = 0.5;
  // At most this many segments per class, drawn at random with `seed` (0: all); keeps training
  // short on datasets with many small derived objects (camvid).
  int max_segments_per_class = 0;
  uint64_t seed = 2009;
  ObjectDescriptionOptions description;

  bool Check(std::string* error) const;
};

// The described segments of a split, one row each.
struct DescribedSegments {
  cv::Mat features;                 // n x ObjectDescriptionSize(k) CV_32F
  std::vector<int> class_ids;       // dataset class id of each row
  std::vector<std::string> images;  // image id of each row
  std::vector<int> objects;         // object id in the image's objects layer
  std::vector<cv::Rect> boxes;      // the object's bounding box in image pixels
  int images_read = 0;

  int size() const { return features.rows; }
};

// Describes every ground-truth object of DIR/<split> (objects/ and classes/ layers required)
// with `textons`; classes named in `exclude` and unlabelled ones are skipped. Progress lines on
// standard error when `progress`.
StatusOr<DescribedSegments> DescribeTruthSegments(const std::string& dataset,
                                                  const std::string& split, const ClassTable& table,
                                                  const TextonAssigner& textons,
                                                  const std::vector<std::string>& exclude,
                                                  const TruthSegmentOptions& options,
                                                  bool progress);

// The same for the segments a segmenter finds instead of the ground-truth objects:
// `objects_of(image)` gives the image's segment id per pixel (CV_32S, 0 = none, any size: it is
// scaled to the image with nearest neighbours). Each segment gets the majority ground-truth
// class of its pixels, as above (at least min_labelled_fraction of it labelled).
StatusOr<DescribedSegments> DescribeSegmentsOf(
    const std::string& dataset, const std::string& split, const ClassTable& table,
    const TextonAssigner& textons, const std::vector<std::string>& exclude,
    const TruthSegmentOptions& options, bool progress,
    const std::function<cv::Mat(const LabelledImage&)>& objects_of);

// One model of the ablation (seed Table 6.5: feature groups; Table 6.6: selection or the full
// set).
struct ObjectModelVariant {
  std::string name;                 // directory under the models directory
  std::vector<std::string> groups;  // FeatureGroup names it reads
  bool select = true;               // seed §4.2 selection, or every column of the groups
};
// "all" (the model) first, then appearance, appearance_parts, appearance_shape, full.
const std::vector<ObjectModelVariant>& ObjectModelVariants();
// The groups of DescriptionGroups(k) a variant reads.
std::vector<FeatureGroup> VariantGroups(const ObjectModelVariant& variant, int k,
                                        int parts_layout_candidates);

struct ObjectTrainingConfig {
  std::string dataset;  // labelled dataset directory
  std::string split = "train";
  std::string out;      // models directory to write (created), e.g. models/objects
  std::string textons;  // textons.yml to describe with; empty: DefaultModelsDir()/textons.yml
  // Dataset class names not trained or evaluated (e.g. horse,mountain: msrc_v2 without them is
  // the seed's MSRC-21).
  std::vector<std::string> exclude_classes;
  // Classes with fewer training segments than this get no classifier (listed in the manifest).
  int min_class_segments = 10;
  TruthSegmentOptions segments;
  ObjectClassifierOptions classifier;
  bool ablation = true;  // also train appearance/, appearance_parts/, appearance_shape/, full/
  bool progress = true;
  std::string command_line;  // recorded in the manifest

  bool Check(std::string* error) const;
};

// Trains and writes the variants and OUT/manifest.json (data, classes with their training
// segment counts, options, selected feature counts per class and group, times); returns the
// manifest. The files are written to OUT/.training-<pid>/ and moved into OUT only when
// everything succeeded, so a failed run leaves OUT's previous models as they were.
StatusOr<nlohmann::json> TrainObjectModels(const ObjectTrainingConfig& config);

// Region accuracy of a classifier over labelled segments (seed §6.2.1: "given a ground truth
// segment, assign a single class label to it"), per class index of one ObjectClassifier.
class ClassificationAccuracy {
 public:
  explicit ClassificationAccuracy(std::vector<std::string> names);
  // One segment of true class `truth` decided `decided` (indices; decided -1: none).
  void Add(int truth, int decided);
  // Percent of segments of class c given class c (NaN without segments).
  double Accuracy(int c) const;
  // Mean of Accuracy over the classes with segments; over `only` of them when not empty.
  double MeanAccuracy(const std::vector<bool>& only = {}) const;
  int Segments(int c) const;
  const std::vector<std::vector<int>>& confusion() const { return confusion_; }
  // {"per_class_accuracy": {name: percent}, "segments": {name: n}, "mean_accuracy",
  //  "overall_accuracy", "confusion": {true name: {decided name: n}}}.
  nlohmann::json ToJson() const;

 private:
  std::vector<std::string> names_;
  std::vector<std::vector<int>> confusion_;  // [truth][decided]
};

}  // namespace placerec
