// placerec-eval segment: segments every image of a labelled dataset's split with Perceptual
// Organization (seed Ch. 3), writes the segmentations, and scores whatever ground truth the
// folder has with the object-level accuracy of seed eq. 6.2 (Table 6.2), next to superpixels
// alone at the best of a small grid of Felzenszwalb-Huttenlocher settings, plus background
// classification accuracy (seed Table 6.4).
#pragma once

#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "common/organization/scene_organizer.h"
#include "common/training/labelled_dataset.h"

namespace placerec {

// Object-level accuracy (seed eq. 6.2) of one image: for every ground-truth object covering at
// least `min_object_fraction` of the image, the intersection over union with the machine segment
// that overlaps it best. `segments` and `objects` are CV_32S of one size (objects: 0 = none);
// `classes` (CV_32S dataset class ids, or empty) gives each object its majority labelled class.
struct ObjectScore {
  int object = 0;          // ground-truth object id
  std::string class_name;  // majority class ("unknown" without class ground truth)
  int pixels = 0;
  double iou = 0.0;
  // Of the best segment: the share of the object it covers and the share of it in the object
  // (low coverage: the object is split; low purity: it is merged with its surroundings).
  double coverage = 0.0;
  double purity = 0.0;
};
std::vector<ObjectScore> ScoreObjects(const cv::Mat& segments, const cv::Mat& objects,
                                      const cv::Mat& classes, const ClassTable& table,
                                      double min_object_fraction);

// Mean IoU over objects, overall and per class, with the aggregates "structured" (objects whose
// class is not a background class) and "background".
class ObjectScoreSummary {
 public:
  void Add(const std::vector<ObjectScore>& scores, const ClassTable& table);
  double Mean() const;
  nlohmann::json ToJson() const;

 private:
  struct Sum {
    double iou = 0;
    double coverage = 0;
    double purity = 0;
    int objects = 0;
  };
  Sum all_;
  std::map<std::string, Sum> classes_;
  std::map<std::string, Sum> groups_;
};

// The options of `placerec-eval segment`, one field per flag; the in-class defaults are the
// flags' defaults.
struct SegmentCommandOptions {
  // Dataset directory (layout of shared/data/README.md), or its name under the default data
  // directory (PLACEREC_DATA / ../shared/data); the images listed in <dataset>/<split>.txt.
  std::string dataset;
  std::string split = "test";
  std::string out;  // output directory (created if missing)
  // The segmentation: superpixels, background classes, learned merging, Perceptual
  // Organization (seed Ch. 3).
  SceneOrganizerOptions organizer = SceneOrganizerOptions::ForSegmentation();
  int overlays = 12;   // overlay pictures to draw, evenly spread over the split
  int max_images = 0;  // segment only the first N images of the split (0: all)
  // Ground-truth objects smaller than this fraction of the image are not scored (seed §6.1.3:
  // 0.5 %).
  double min_object_fraction = 0.005;
  // The superpixel baseline (when `baseline`): every pair of FH k and minimum size (pixels),
  // both at 320x240, comma-separated; the best pair's score is reported.
  bool baseline = true;
  std::string grid_k = "125,250,500,1000";
  std::string grid_min = "50,150,300";
  bool quiet = false;    // no progress line
  bool verbose = false;  // one line per image: parts per round, segments, IoU
  // Diagnosis only: superpixels take the background class of their ground-truth majority
  // class (oracle_classes), or the initial partition's regions are grouped by their majority
  // ground-truth object (oracle_grouping).
  bool oracle_classes = false;
  bool oracle_grouping = false;

  // Organizer options valid, grid lists numbers (with the baseline), dataset/out/split not
  // empty, overlays and max_images >= 0, min_object_fraction in [0, 1).
  bool Check(std::string* error) const;
};

// `placerec-eval segment ...`; argv[1] is "segment". Returns the process exit code: 0, 2 for
// bad flags (SegmentCommandOptions::Check), 1 when reading, segmenting or writing fails.
int SegmentCommand(int argc, char** argv, const std::string& default_data_dir);

}  // namespace placerec
