// placerec-train background: learns the textons and the five background classifiers of seed
// §3.4 from a labelled dataset (stanford_background train by default) and writes them, with a
// manifest, into a models directory. Also the region bookkeeping that the segment command
// shares: region labels from ground truth and background accuracy (seed Table 6.4).
#pragma once

#include <array>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "common/organization/background.h"
#include "common/organization/scene_organizer.h"
#include "common/organization/textons.h"
#include "common/training/labelled_dataset.h"
#include "common/util/status.h"

namespace placerec {

// Today's date in UTC as YYYY-MM-DD (the "created" field of the training manifests).
std::string TodayUtc();

// Writes a training manifest (or any JSON) to `path`, indented, with a trailing newline.
Status WriteManifest(const std::string& path, const nlohmann::json& manifest);

// Pixels of every region 0..n-1 of `regions` (other ids ignored).
std::vector<int> RegionAreas(const cv::Mat& regions, int n);

// Label of every region of `regions` (CV_32S ids 0..n-1 at the size of `gt_classes`, CV_32S
// dataset class ids): the background class (0..4) or 7 of the majority class among its labelled
// pixels, or -1 when fewer than `min_labelled_fraction` of its pixels are labelled. The majority
// class ids themselves go to `majority` when not null (-1 when unlabelled).
std::vector<int> RegionLabels(const cv::Mat& regions, int n, const cv::Mat& gt_classes,
                              const ClassTable& table, double min_labelled_fraction,
                              std::vector<int>* majority = nullptr);

// Background classification accuracy on labelled regions (seed Table 6.4): per background
// class, the share of its regions the five-way decision calls that class, and each binary
// classifier's accuracy over all regions.
struct BackgroundAccuracy {
  std::array<int, kBackgroundClasses> regions{};             // regions of the class
  std::array<int, kBackgroundClasses> correct{};             // ... decided as the class
  std::array<int, kBackgroundClasses> called{};              // regions decided as the class
  std::array<int, kBackgroundClasses> binary_correct{};      // classifier right (yes/no)
  std::array<int64_t, kBackgroundClasses> pixels{};          // pixels of regions of the class
  std::array<int64_t, kBackgroundClasses> correct_pixels{};  // ... in regions decided right
  std::array<int64_t, kBackgroundClasses> called_pixels{};   // pixels of regions decided so
  int structured_regions = 0;                                // regions of other classes
  int structured_correct = 0;                                // ... decided structured
  int total = 0;
  // Dataset class name -> regions decided sky, tree, road, grass, water, structured.
  std::map<std::string, std::array<int, kBackgroundClasses + 1>> confusion;

  // `scores`: BackgroundClassifier::Scores rows; `rivals`: BackgroundClassifier::Rivals of the
  // same rows; labels and majority class ids from
  // RegionLabels (-1 rows skipped); names from `table`.
  // `areas` (pixels per region) weighs the pixel counts.
  void Add(const cv::Mat& scores, const std::vector<float>& rivals, const std::vector<int>& labels,
           const std::vector<int>& majority, const std::vector<int>& areas, const ClassTable& table,
           double threshold);
  nlohmann::json ToJson() const;
};

struct BackgroundTrainingConfig {
  // Labelled dataset directories (at least one). Training pools the `split` images of all of
  // them (each labelled through its own classes.txt: BackgroundClassOfName, StructuredClassIndex);
  // each one's `eval_split` is scored on its own, and the check sample comes from the first.
  std::vector<std::string> datasets;
  std::string split = "train";
  std::string eval_split = "test";  // accuracy reported in the manifest ("" or missing: none)
  std::string out;                  // models directory (created)
  // Pixels sampled per training image for k-means (seed §3.4 clusters "all training pixels";
  // a sample keeps training short).
  int pixels_per_image = 300;
  TextonTrainingOptions textons;
  // When not empty, the textons are read from this file (of textons.k centres) instead of
  // learned, and copied into `out` (keeps the dictionary models/objects was described with).
  std::string textons_file;
  BackgroundTrainingOptions boost;
  // Working resolution, initial partition and texton stride: the ones segmentation uses.
  SceneOrganizerOptions organizer = SceneOrganizerOptions::ForSegmentation();
  // Training regions: the superpixels of each image and/or its ground-truth object regions (the
  // seed trains on ground-truth segments, §6.2.2).
  bool superpixel_regions = true;
  bool ground_truth_regions = true;
  // Region features: the seed's texton histogram and height (false), or those plus the mean
  // and standard deviation of each filter-bank feature (true, kAppearanceExtras; textons.h).
  bool appearance_extras = true;
  // Superpixels whose labelled share is below this are left out; so are regions smaller than
  // min_region_pixels (working pixels).
  double min_labelled_fraction = 0.5;
  int min_region_pixels = 30;
  // Structured classes that get a classifier of their own (for the one-per-class decision):
  // dataset class names; {"all"}: every labelled class that is not a background class; empty:
  // none (the five background classifiers only).
  std::vector<std::string> structured_classes = {"all"};
  // The first `holdout` images of each dataset's `split` are left out of training (validation).
  int holdout = 0;
  // When not empty, this fold of the images after the holdout is left out too (for the
  // cross-fitted grouping training of grouping_training.h).
  Fold leave_out_fold;
  // A training region's initial boosting weight is its area (working pixels) to this power:
  // 0 weighs every region alike, 1 weighs by pixels.
  double area_weight_power = 0.0;
  uint64_t seed = 2009;
  // Regions of the first images of eval_split (ground-truth objects) are stored as the fixed
  // check sample (check_sample.yml.gz) with the accuracy they had at training time.
  int check_images = 8;
  bool progress = true;
  // The invocation (CommandLine of util/options.h), recorded in the manifest so the models
  // can be retrained with exactly these options; empty when not run from the command line.
  std::string command_line;

  // At least one dataset, none empty; non-empty split and out; pixels_per_image, min_region_pixels
  // >= 1; holdout, check_images >= 0; min_labelled_fraction in [0, 1]; a finite area_weight_power;
  // no empty structured class name; a valid fold; and the textons', boosting's and organizer's
  // Check. What needs the dataset (the holdout leaving images, the classes existing) is checked by
  // TrainBackgroundModels.
  bool Check(std::string* error) const;
};

// stanford_background's class for every object that is neither background nor building nor
// mountain (cars, people, signs, ...): a structured class of that name also learns the
// non-background classes of another dataset that are not structured classes of their own.
constexpr char kCatchAllStructuredClass[] = "foreground";

// Which structured classifier learns each class of `table` (dataset class id -> index into
// `names`): a class named in `names`; otherwise, when `names` has kCatchAllStructuredClass and
// `table` has no class of that name, that one (camvid's car, msrc_v2's cow); otherwise none.
// Unlabelled and background classes (BackgroundClassOfName) are never in it.
std::map<int, int> StructuredClassIndex(const std::vector<std::string>& names,
                                        const ClassTable& table);

// Runs the whole training and writes OUT/textons.yml, OUT/background*.yml*,
// OUT/check_sample.yml.gz and OUT/manifest.json; returns the manifest. The files are written
// to OUT/.training-<pid>/ and moved into OUT only when everything succeeded, so a failed run
// leaves OUT as it was (an interrupted one leaves only that hidden directory, safe to delete).
// The evaluation split's images are read first, and training images that lack a class's
// regions (or have nothing else) are an error, not a crash.
StatusOr<nlohmann::json> TrainBackgroundModels(const BackgroundTrainingConfig& config);

}  // namespace placerec
