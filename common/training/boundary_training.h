// placerec-train boundary: learns the boundary classifier of common/organization/boundary.h
// from a labelled dataset's object ground truth (stanford_background train by default).
//
// Training pixels are the pixels on superpixel boundaries (the cracks the learned region
// merging reads, with the same initial partition): a pixel within `positive_distance` of a
// ground-truth object boundary is an object boundary, one at least `negative_distance` from every
// object boundary is not, and those in between (where the annotation's own placement is
// uncertain) are left out. So the classifier learns what the merging needs: to tell the
// superpixel boundaries that separate objects from those inside one.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "common/organization/boundary.h"
#include "common/organization/scene_organizer.h"
#include "common/training/labelled_dataset.h"
#include "common/util/status.h"

namespace placerec {

struct BoundaryTrainingConfig {
  std::string dataset;  // labelled dataset directory (needs objects/)
  std::string split = "train";
  std::string eval_split = "test";  // its accuracy goes into the manifest ("" to skip)
  // The first `holdout` images of the split are not trained on; their accuracy is reported.
  int holdout = 0;
  // Also leaves out this fold of the images after the holdout (labelled_dataset.h), for the
  // cross-fitted grouping models (placerec-train grouping --cross-fit reads a boundary model
  // from each fold's directory when there is one).
  Fold leave_out_fold;
  std::string out;  // models directory: writes boundary.yml.gz and boundary.json
  // Pixels drawn per image and label (at most; fewer when the image has fewer).
  int samples_per_image = 250;
  // Distance (pixels, working resolution) from the nearest ground-truth object boundary.
  double positive_distance = 1.0;
  double negative_distance = 3.0;
  BoundaryModel::TrainingOptions boost;
  SceneOrganizerOptions organizer =  // working width and initial partition
      SceneOrganizerOptions::ForSegmentation();
  uint64_t seed = 2009;
  bool progress = true;
  std::string command_line;  // recorded in the manifest

  // Non-empty dataset, split and out; samples_per_image >= 1; holdout >= 0; a valid fold;
  // 0 <= positive_distance < negative_distance; and the boosting's and organizer's Check.
  bool Check(std::string* error) const;
};

// Trains and writes OUT/boundary.yml.gz and OUT/boundary.json (the manifest); returns the
// manifest.
StatusOr<nlohmann::json> TrainBoundaryModel(const BoundaryTrainingConfig& config);

}  // namespace placerec
