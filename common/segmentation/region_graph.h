// The region adjacency graph of a segmentation (seed §3.7: G = (V, E), one vertex per
// superpixel, one edge per pair of neighbours), with the per-region measurements Perceptual
// Organization needs. Lengths are in working pixels: a boundary is counted in unit pixel edges
// between 4-neighbours, so L(d(A u B)) = L(dA) + L(dB) - 2 L(dAB) holds exactly (seed Lemma 1).
#pragma once

#include <utility>
#include <vector>

#include <opencv2/core.hpp>

namespace placerec {

// Measurements of one region in working pixels. A label that does not occur has area 0, an
// empty box and zero centroid and colour.
struct RegionStats {
  int area = 0;          // pixels
  int perimeter = 0;     // unit pixel edges on the region's boundary, image border included
  cv::Point2d centroid;  // mean pixel position (x, y), pixel centres at integers
  cv::Rect box;          // bounding box
  cv::Vec3f mean_lab;    // mean CIE Lab colour
};

struct RegionGraph {
  std::vector<RegionStats> regions;
  // neighbours[i]: (neighbour id, shared boundary length in unit pixel edges), sorted by id.
  std::vector<std::vector<std::pair<int, int>>> neighbours;

  int size() const { return static_cast<int>(regions.size()); }
  // Shared boundary length of regions a and b (0 when not adjacent or a == b); binary search.
  // Both ids must be in 0..size()-1.
  int SharedBoundary(int a, int b) const;
};

// Builds the graph of `labels` (CV_32S, ids 0..num_regions-1; an id outside that range is a
// programming error and aborts) with colours from `lab` (CV_32FC3, same size; an empty Mat
// leaves mean_lab at zero), in one pass over the pixels.
RegionGraph BuildRegionGraph(const cv::Mat& labels, int num_regions, const cv::Mat& lab);

}  // namespace placerec
