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

// `placerec-eval segment ...`; argv[1] is "segment". Returns the process exit code.
int SegmentCommand(int argc, char** argv, const std::string& default_data_dir);

}  // namespace placerec
