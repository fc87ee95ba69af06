// The segmentation every later stage consumes: a label per pixel and a class per segment.
// Superpixels (pipeline step 3) produce one with every segment "structured"; Perceptual
// Organization (step 5, seed Ch. 3) produces one with grouped objects and background classes.
// Objects (step 6) read only this type, so either producer slots in without changes downstream.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace placerec {

// Class of a segment. Values are the ids of stanford_background/classes.txt for the background
// classes (seed §3.4) and 7 for structured segments (candidate objects or object parts).
enum class SegmentClass : uint8_t {
  kSky = 0,
  kTree = 1,
  kRoad = 2,
  kGrass = 3,
  kWater = 4,
  kStructured = 7,
};

const char* SegmentClassName(SegmentClass segment_class);
bool IsBackground(SegmentClass segment_class);
// Whether `value` is the number of a SegmentClass enumerator; values read from a map file or sent
// by a robot may be anything else.
bool IsKnownSegmentClass(int64_t value);

// The frame at the resolution segmentation works at (seed §6.1: about 320x240).
struct WorkingImage {
  cv::Mat bgr;         // CV_8UC3
  cv::Mat lab;         // CV_32FC3, CIE Lab (L in [0, 100])
  double scale = 1.0;  // working pixels per full-resolution pixel (<= 1)
};

// Resizes `bgr` (8-bit BGR, INTER_AREA) so that its width is at most `working_width` pixels
// (0 keeps it; the height is rounded to keep the aspect ratio) and computes its Lab image.
// scale = working width / original width. Without resizing, `bgr` shares data with the input.
WorkingImage MakeWorkingImage(const cv::Mat& bgr, int working_width);

struct SceneSegmentation {
  cv::Mat labels;                     // CV_32S, segment id per working pixel, 0..size()-1
  std::vector<SegmentClass> classes;  // one per segment
  double scale = 1.0;                 // working pixels per full-resolution pixel

  int size() const { return static_cast<int>(classes.size()); }
  // Segment under a full-resolution point (e.g. a keypoint, pixel centres at integers): the
  // working pixel floor((x + 0.5) * scale), floor((y + 0.5) * scale), clamped to the label image
  // when it lies up to half a working pixel past the last column or row (the working height is
  // rounded); -1 further outside (or NaN).
  int SegmentAt(float x, float y) const;
};

// Renumbers labels to 0..n-1 in order of first appearance (row-major) and returns n.
int CompactLabels(cv::Mat* labels);

}  // namespace placerec
