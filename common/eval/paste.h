// Ground truth for scene-change detection (seed §7.2.4, `placerec-eval change`): real objects cut
// by their ground-truth masks from a labelled dataset's test split (../shared/data layout:
// images/, classes/, objects/, test.txt), pasted into a frame at a chosen share of its area with
// feathered, colour-matched edges; and "removals", a region painted over with the background
// around it. The box each leaves is what a detector must find.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "common/util/status.h"

namespace placerec {

// An object cut from a labelled image: its pixels and mask (the mask's bounding box).
struct CutObject {
  cv::Mat bgr;   // CV_8UC3
  cv::Mat mask;  // CV_8U, 255 on the object
  std::string class_name;
  std::string source;  // "<dataset>/<id>#<object id>"
};

struct CutOptions {
  // Class names (classes.txt of the dataset) whose objects are cut.
  std::vector<std::string> classes = {"car", "pedestrian", "signsymbol", "bicyclist"};
  int min_pixels = 900;  // smallest object mask, pixels
  // Objects filling less than this share of their box (thin poles, fragments) are skipped.
  double min_fill = 0.3;
  int max_objects = 300;  // stop after this many
};

// The objects of the test split of the dataset at `dataset_dir` (images/<id>.jpg,
// classes/<id>.png, objects/<id>.png, classes.txt, test.txt) whose majority class is one of
// options.classes, in test.txt order. NotFound when the dataset or its test split is missing.
StatusOr<std::vector<CutObject>> CutTestObjects(const std::string& dataset_dir,
                                                const CutOptions& options);

// Pastes `object` into `frame` scaled so that its mask covers `area_share` of the frame, at
// (x, y) in [0, 1] of the free range; edges feathered over a few pixels and the object's mean
// colour (CIE Lab) moved `colour_shift` of the way to that of the region it covers (0: the
// object's own colours, 1: the region's mean). Returns the mask's box in the frame (empty when the
// object cannot be scaled to fit); *covered_share, when given, is the share of the frame the
// pasted mask covers (about `area_share`; its box covers more).
cv::Rect PasteObject(const CutObject& object, double area_share, double x, double y,
                     double colour_shift, cv::Mat* frame, double* covered_share = nullptr);

// Paints `box` of `frame` over with the surroundings (inpainting from its border): a landmark
// removed. Returns the painted box (clipped to the frame).
cv::Rect PaintOver(const cv::Rect& box, cv::Mat* frame);

// Intersection over union of two boxes (0 when either is empty).
double BoxIoU(const cv::Rect& a, const cv::Rect& b);

}  // namespace placerec
