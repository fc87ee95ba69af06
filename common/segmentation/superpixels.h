// Pipeline step 3 (DESIGN.md; seed §3.6, §6.1.2): Felzenszwalb-Huttenlocher superpixels, then
// regions under 0.03 % of the image merged into a neighbour, then adjacent regions of similar
// colour merged. The result ("improved superpixels") approximates object parts.
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "common/segmentation/segmentation.h"

namespace placerec {

struct SuperpixelOptions {
  // Segmentation runs on the frame scaled to this width in pixels (seed §6.1: about 320x240);
  // 0 runs at the frame's own size.
  int working_width = 320;
  // Felzenszwalb-Huttenlocher Gaussian pre-smoothing sigma in pixels (seed §6.1.2).
  double sigma = 0.5;
  // FH threshold constant k for a 640x480 image (seed §6.1.2: k = 300). FH's threshold k/|C|
  // compares with component sizes in pixels, so k is scaled by working area / (640 * 480).
  double k = 300.0;
  // FH minimum component size in pixels for a 640x480 image (seed §6.1.2: min = 20), scaled by
  // area like k (and never below 1).
  int min_size = 20;
  // Regions smaller than this fraction of the image are merged into the neighbour they share
  // the longest boundary with (seed §3.6: 0.03 %).
  double min_region_fraction = 0.0003;
  // Adjacent regions whose mean CIE Lab colours differ by less than this (Delta E 1976) are
  // merged (seed §3.6, "similar colours"; the seed gives no number). 0 disables.
  double colour_merge_distance = 5.0;

  bool Check(std::string* error) const;
};

// Improved superpixels of a working image: every segment is kStructured, labels compact.
SceneSegmentation ComputeSuperpixels(const WorkingImage& image, const SuperpixelOptions& options);

}  // namespace placerec
