// placerec-train grouping: learns the region-merge classifier of region_merging.h from a
// labelled dataset's object ground truth (stanford_background train by default).
//
// Training pairs come from the superpixels of every training image and from the larger regions
// that appear while those superpixels are merged by their ground-truth objects, so the model
// sees pairs of the sizes it meets during its own greedy merging: a pair is positive when both
// regions' majority object is the same, negative when it differs (regions whose majority object
// covers less than half of them are left out). A second pass (`on_policy`) then lets the first
// model merge the superpixels greedily itself (down to `policy_threshold`) and adds the pairs it
// meets after every merge, mistakes included, and trains again, so the final model also learns
// from the impure regions its own merging produces. The shipped model averages four: with and
// without that pass, each plain and cross-fitted (`cross_fit`; placerec-train
// grouping-ensemble; models/README.md).
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/organization/region_merging.h"
#include "common/organization/scene_organizer.h"
#include "common/util/status.h"

namespace placerec {

struct GroupingTrainingConfig {
  std::string dataset;  // labelled dataset directory (needs objects/)
  std::string split = "train";
  // The first `holdout` images of the split are not trained on (for choosing the merge
  // threshold on images the model has not seen).
  int holdout = 0;
  // Cross-fitting: when not empty, K >= 2 models directories, the k-th trained by
  // `placerec-train background --holdout <holdout> --leave-out-fold k/K` on the same dataset and
  // split. The images after the holdout form K folds (labelled_dataset.h), and fold k is
  // described with directory k's textons and classifiers, which never saw it; so the pairs'
  // background scores are as good as they are on new images, not as good as on training ones.
  // Empty: every image is described with `out`'s models.
  std::vector<std::string> cross_fit;
  std::string out;  // models directory: reads textons and classifiers, writes grouping.yml.gz
  // Ground-truth merges between recorded states: each level merges this share of the
  // then-possible same-object pairs; states are recorded before the first level and after each.
  int levels = 3;
  double level_fraction = 0.5;
  // Regions whose majority object covers less than this share are left out of training pairs.
  double min_purity = 0.5;
  // The second (on-policy) pass, and how far its greedy merging goes.
  bool on_policy = true;
  double policy_threshold = -0.5;
  // Each model trains on at most this many pairs, drawn at random (0: all).
  int max_pairs = 200000;
  // The leading columns of the pair features the model reads (region_merging.h).
  int features = kMergeRelationFeatures;
  RegionMergeModel::TrainingOptions boost;
  SceneOrganizerOptions organizer =  // working width, initial partition, texton stride
      SceneOrganizerOptions::ForSegmentation();
  uint64_t seed = 2009;
  bool progress = true;
  // The invocation (CommandLine of util/options.h), recorded in the manifest; empty when not
  // run from the command line.
  std::string command_line;

  // Non-empty dataset, split and out; holdout, levels, max_pairs >= 0; level_fraction and
  // min_purity in (0, 1]; a finite policy_threshold; features in 1..kMergeFeatures; cross_fit
  // empty or at least two non-empty directories; and the boosting's and organizer's Check (the
  // organizer without the learned merging, which training does not use).
  bool Check(std::string* error) const;
};

// Trains and writes OUT/grouping.yml.gz and OUT/grouping.json (the manifest); returns the
// manifest.
StatusOr<nlohmann::json> TrainGroupingModel(const GroupingTrainingConfig& config);

}  // namespace placerec
