// placerec-train background: learns the textons and the five background classifiers of seed
// §3.4 from a labelled dataset (stanford_background train by default) and writes them, with a
// manifest, into a models directory. Also the region bookkeeping that the segment command
// shares: region labels from ground truth and background accuracy (seed Table 6.4).
#pragma once

#include <array>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "common/organization/background.h"
#include "common/organization/scene_organizer.h"
#include "common/organization/textons.h"
#include "common/util/status.h"
#include "tools/labelled_dataset.h"

namespace placerec {

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
  std::array<int, kBackgroundClasses> regions{};          // regions of the class
  std::array<int, kBackgroundClasses> correct{};          // ... decided as the class
  std::array<int, kBackgroundClasses> called{};           // regions decided as the class
  std::array<int, kBackgroundClasses> binary_correct{};   // classifier right (yes/no)
  int structured_regions = 0;     // regions of other classes
  int structured_correct = 0;     // ... decided structured
  int total = 0;

  // `scores`: BackgroundClassifier::Scores rows; labels from RegionLabels (-1 rows skipped).
  void Add(const cv::Mat& scores, const std::vector<int>& labels, double threshold);
  nlohmann::json ToJson() const;
};

struct BackgroundTrainingConfig {
  std::string dataset;         // labelled dataset directory
  std::string split = "train";
  std::string eval_split = "test";  // accuracy reported in the manifest ("" or missing: none)
  std::string out;                  // models directory (created)
  // Pixels sampled per training image for k-means (seed §3.4 clusters "all training pixels";
  // a sample keeps training short).
  int pixels_per_image = 300;
  TextonTrainingOptions textons;
  BackgroundTrainingOptions boost;
  // Working resolution, initial partition and texton stride: the ones segmentation uses.
  SceneOrganizerOptions organizer;
  // Training regions are the superpixels of each image, plus its ground-truth object regions
  // when set (the seed trains on ground-truth segments, §6.2.2).
  bool ground_truth_regions = true;
  // Superpixels whose labelled share is below this are left out; so are regions smaller than
  // min_region_pixels (working pixels).
  double min_labelled_fraction = 0.5;
  int min_region_pixels = 30;
  uint64_t seed = 2009;
  // Regions of the first images of eval_split (ground-truth objects) are stored as the fixed
  // check sample (check_sample.yml.gz) with the accuracy they had at training time.
  int check_images = 8;
  bool progress = true;
};

// Runs the whole training and writes OUT/textons.yml, OUT/background*.yml*,
// OUT/check_sample.yml.gz and OUT/manifest.json; returns the manifest.
StatusOr<nlohmann::json> TrainBackgroundModels(const BackgroundTrainingConfig& config);

}  // namespace placerec
