// Pipeline step 3 (DESIGN.md; seed §3.6, §6.1.2): Felzenszwalb-Huttenlocher superpixels, then
// regions under 0.03 % of the image merged into a neighbour, then adjacent regions of similar
// colour merged. The result ("improved superpixels") approximates object parts.
//
// FH is our own implementation (FelzenszwalbSegmentation below), not cv::ximgproc's: the same
// algorithm on the 8-connected graph of the paper (ximgproc uses 4-neighbours), faster because
// the edges are radix-sorted instead of std::sort-ed (the timing is in
// docs/experiments/2026-11-22-segmentation-defaults.md).
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "common/segmentation/segmentation.h"

namespace placerec {

struct SuperpixelOptions {
  // Segmentation runs on the frame scaled to this width in pixels (seed §6.1: about 320x240);
  // 0 runs at the frame's own size. The caller applies it: MakeWorkingImage(frame,
  // working_width), whose result the later stages share.
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

// What one ComputeSuperpixels call did: the region count after each step and the wall-clock
// time each step took (milliseconds).
struct SuperpixelSummary {
  int fh_regions = 0;         // components of the Felzenszwalb-Huttenlocher partition
  int after_small_merge = 0;  // after merging regions under min_region_fraction
  int segments = 0;           // after merging similar colours: the result
  double fh_ms = 0.0;
  double small_merge_ms = 0.0;   // includes the region graph of the FH partition
  double colour_merge_ms = 0.0;  // includes relabelling the pixels
};

// Improved superpixels of a working image: every segment is kStructured, labels compact (in
// order of first appearance), scale copied from the working image. `options` must pass Check.
//  1. FH with k and min_size scaled to the working area.
//  2. Regions under min_region_fraction of the image, smallest first, join the neighbour they
//     share the longest boundary with (ties: the larger neighbour, then the lower id), until
//     none is left.
//  3. Adjacent pairs whose mean Lab colours are closer than colour_merge_distance merge in
//     order of increasing distance; each merge is re-checked against the current means of the
//     merged groups, so a chain of slowly changing colours does not collapse into one segment.
// Deterministic: the same image and options give the same labels.
SceneSegmentation ComputeSuperpixels(const WorkingImage& image, const SuperpixelOptions& options);
// The same, and fills `summary` when it is not null.
SceneSegmentation ComputeSuperpixels(const WorkingImage& image, const SuperpixelOptions& options,
                                     SuperpixelSummary* summary);

// Felzenszwalb-Huttenlocher graph segmentation [Felzenszwalb04] of an 8-bit BGR image, the first
// step of ComputeSuperpixels: Gaussian pre-smoothing with `sigma` pixels (0: none), an
// 8-connected grid graph with Euclidean RGB edge weights, components joined while an edge weighs
// at most Int(C) + k / |C| for both sides, then components under `min_size` pixels joined along
// the lightest edges. `k` and `min_size` are used as given (not scaled). Returns CV_32S labels
// 0..n-1 in order of first appearance and n through `num_components`.
cv::Mat FelzenszwalbSegmentation(const cv::Mat& bgr, double sigma, double k, int min_size,
                                 int* num_components);

}  // namespace placerec
