// Domain types of the landmark map (seed §5.3, §5.7): places are frames that robots inserted,
// landmarks are the widely visible objects stored for a place.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "common/objects/objects.h"
#include "common/segmentation/segmentation.h"
#include "common/util/ids.h"
#include "common/util/status.h"

namespace placerec {

// Longest robot id the map accepts (bytes).
constexpr size_t kMaxRobotIdLength = 64;
// Largest place thumbnail a store accepts (bytes of JPEG).
constexpr size_t kMaxThumbnailBytes = 1 << 20;
// Longest object class name a landmark keeps (bytes).
constexpr size_t kMaxObjectClassLength = 32;
// Latest capture time the map accepts: the end of the year 9999 in microseconds since the epoch.
// Times lie in 0 .. kMaxUtime, so that the differences the map takes between them (vote windows,
// a robot's recent past) cannot overflow.
constexpr int64_t kMaxUtime = 253402300799999999;

// Longest time window an option may give (seconds; a day): windows are compared in
// microseconds, and no place is one location with another for longer.
constexpr double kMaxWindowSeconds = 86400.0;

// InvalidArgument naming the range when `utime` lies outside 0 .. kMaxUtime.
Status CheckCaptureTime(int64_t utime);
// `utime` moved into 0 .. kMaxUtime (the nearest end when outside): the time a map serves a place
// by whose stored time an old build wrote outside the range.
inline int64_t ClampCaptureTime(int64_t utime) {
  return utime < 0 ? 0 : (utime > kMaxUtime ? kMaxUtime : utime);
}

// One inserted frame of one robot.
struct Place {
  PlaceId id;
  std::string robot;     // robot id, 1..kMaxRobotIdLength bytes
  int64_t sequence = 0;  // the robot's frame sequence number (monotonic per robot)
  int64_t utime = 0;     // capture time, microseconds since the epoch
  int num_landmarks = 0;
  int image_width = 0;  // width in pixels of the processed frame its keypoints refer to
  // Landmarks stored with earlier places that this place saw again (the seed's object database,
  // §5.7 step 5: a matched landmark's scene set gains the place instead of the landmark being
  // stored twice). Empty except in the seed's recognition mode. Increasing ids.
  std::vector<LandmarkId> seen_landmarks = {};
  // A small JPEG of the frame (about 160 px wide, AnalyzerOptions::thumbnail_width) that alarms,
  // matches and tools show as the stored view, and that scene-change detection compares with
  // (seed §7.2.4). Written by LandmarkStore::AddPlace, read back only by
  // LandmarkStore::LoadThumbnail (LoadPlaces leaves it empty); not part of operator==. Empty:
  // none (maps written before schema v3, or thumbnails off). At most kMaxThumbnailBytes.
  std::vector<uint8_t> thumbnail = {};

  bool operator==(const Place& other) const {
    return id == other.id && robot == other.robot && sequence == other.sequence &&
           utime == other.utime && num_landmarks == other.num_landmarks &&
           image_width == other.image_width && seen_landmarks == other.seen_landmarks;
  }

  // What every landmark store requires of a place (LandmarkStore::AddPlace): a robot id of
  // 1..kMaxRobotIdLength bytes without NUL bytes, image_width >= 0, seen_landmarks valid
  // ids, increasing, and a thumbnail of at most kMaxThumbnailBytes. InvalidArgument otherwise.
  // The id and num_landmarks are the store's to set and are not checked.
  Status Validate() const;
};

// A stored landmark object.
struct Landmark {
  LandmarkId id;
  PlaceId place;
  int sift_count = 0;      // SIFT keypoints on the object when it was seen (texture, seed §5.5)
  ColourSignature colour;  // dominant H peaks (seed §5.6)
  cv::Rect box;            // full-resolution pixels in the place's frame
  SegmentClass segment_class = SegmentClass::kStructured;
  cv::Mat descriptors;                  // CV_8U, the stored SIFT descriptors, one 128-byte row each
  std::vector<cv::KeyPoint> keypoints;  // one per stored descriptor (x, y, size, angle kept)
  // The object's class (seed Ch. 4, common/classification): a class name of the object
  // classifier, e.g. "building" or "car"; empty when the object was not classified (maps of
  // schema v1, or a server without object models).
  std::string object_class;
  // How sure the classifier was of object_class, in [0, 1]; 0 when there is no class.
  float class_confidence = 0.0f;

  int num_descriptors() const { return descriptors.rows; }

  // What every landmark store requires of a landmark (LandmarkStore::AddPlace): descriptors CV_8U
  // with one channel, kDescriptorSize columns and continuous in memory, or an empty matrix; one
  // keypoint per descriptor row; sift_count >= 0; a known segment class; a box of non-negative
  // size; an object class of at most kMaxObjectClassLength bytes, each an ASCII letter, digit,
  // '_' or '-', with a confidence in [0, 1] (0 without a class). InvalidArgument otherwise. The
  // id and place are the store's to set and are not checked.
  Status Validate() const;
};

// Validates a place and the landmarks stored with it, in that order; a landmark's error starts
// with its index ("landmark 2: ..."). At most INT_MAX landmarks (Place::num_landmarks is an int).
Status ValidatePlaceAndLandmarks(const Place& place, const std::vector<Landmark>& landmarks);

}  // namespace placerec
