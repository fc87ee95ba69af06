// Reading the labelled scene-image layout of shared/data/README.md (stanford_background,
// msrc_v2): images/<id>.jpg, classes/<id>.png, objects/<id>.png, classes.txt, <split>.txt.
// Only the images and the split list are required; ground truth is used when present.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "common/segmentation/segmentation.h"
#include "common/util/status.h"

namespace placerec {

// The one place where dataset class names meet the background classes of seed §3.4 (sky, tree,
// road, grass, water), for training, `placerec-eval segment` and `placerec-eval classify` alike:
// a class named like a background class is that class (stanford_background, msrc_v2, camvid's
// sky, road, tree); the aliases below name the rest (shared/data/README.md: camvid's pavement is
// ground, like road); every other name is structured (building, mountain, car, ...).
SegmentClass BackgroundClassOfName(const std::string& name);

// classes.txt: "id name" per line.
struct ClassTable {
  std::map<int, std::string> names;

  bool empty() const { return names.empty(); }
  std::string Name(int id) const;  // "class<id>" when unlisted
  // Ids that mean "no label": those named unknown, void or unlabelled.
  bool IsUnlabelled(int id) const;
  // The background class a dataset class stands for, by name (BackgroundClassOfName);
  // kStructured for every other class and for unlisted ids.
  SegmentClass BackgroundClass(int id) const;
};

// Reads DIR/classes.txt; an empty table when the file is missing.
StatusOr<ClassTable> ReadClassTable(const std::string& dir);

// Ids listed in DIR/<split>.txt, in order.
StatusOr<std::vector<std::string>> ReadSplit(const std::string& dir, const std::string& split);

struct LabelledImage {
  std::string id;
  cv::Mat bgr;      // CV_8UC3
  cv::Mat classes;  // CV_8U class id per pixel, or empty when DIR/classes/<id>.png is missing
  cv::Mat objects;  // CV_8U or CV_16U object id per pixel (0 = none), or empty
};

// Reads DIR/images/<id>.jpg (or .png) and, when present, its ground-truth layers; a layer whose
// size differs from the image's is an error.
StatusOr<LabelledImage> ReadLabelledImage(const std::string& dir, const std::string& id);

// A ground-truth layer brought to the working resolution (nearest neighbour), as CV_32S.
cv::Mat LayerAtSize(const cv::Mat& layer, cv::Size size);

// Cross-fitting folds of placerec-train: the images of a split after its held-out first ones
// form `count` contiguous chunks of near-equal size; fold `index` is one of them. Background
// models trained without fold i describe fold i's images when the grouping model is trained,
// so the grouping model learns from background scores as good as they are on unseen images.
struct Fold {
  int index = 0;
  int count = 0;  // 0: no fold

  bool empty() const { return count == 0; }
  std::string ToString() const;  // "I/K", or "" when empty
  // Empty, or 0 <= index < count with count >= 2 (what ParseFold accepts).
  bool Check(std::string* error) const;
};

// Parses "I/K" with 0 <= I < K and K >= 2; "" gives an empty fold.
StatusOr<Fold> ParseFold(const std::string& text);

// The fold (0..count-1) of the image at `position` among `total` (count >= 1, total >= 1).
int FoldOf(size_t position, size_t total, int count);

// Work over a dataset's images (training, `placerec-eval segment`) writes a progress line to a
// log (anything but a terminal, see ProgressLine) every this many images.
constexpr size_t kLogProgressEvery = 50;

}  // namespace placerec
