// The BLOB encodings of the landmark map (schema v1, common/storage/schema.h), independent of the
// database that holds them: colour peaks as float32 little-endian, one per peak; descriptors as
// num_descriptors rows of kDescriptorSize bytes (CV_8U); keypoints as float32 little-endian x, y,
// size, angle, one per descriptor. Checksum() hashes these bytes as they are stored.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "common/recognition/types.h"
#include "common/util/status.h"

namespace placerec {

// Bytes of one stored colour peak: float32, little-endian.
constexpr size_t kPeakBytes = 4;
// Bytes of one stored keypoint: float32 x, y, size, angle, little-endian.
constexpr size_t kKeypointBytes = 16;

// Bytes held elsewhere (e.g. in SQLite's row buffer, or a landmark's descriptor matrix);
// {nullptr, 0} when there are none.
struct ByteView {
  const uint8_t* data = nullptr;
  size_t size = 0;
};

// A landmark as it is stored: its integer fields (int64, as the database reads them) and its BLOBs,
// which point into buffers that must outlive this view.
struct EncodedLandmark {
  int64_t id = 0;
  int64_t place = 0;
  int64_t sift_count = 0;
  ByteView peaks;
  int64_t segment_class = 0;
  int64_t box[4] = {0, 0, 0, 0};  // x, y, width, height in full-resolution pixels
  int64_t num_descriptors = 0;
  ByteView descriptors;
  ByteView keypoints;
  // Schema v2: the object class (empty when unclassified) and the classifier's confidence.
  std::string object_class;
  float class_confidence = 0.0f;
};

// Buffers for the BLOBs that EncodeLandmark has to build; reuse them across calls.
struct LandmarkBlobBuffers {
  std::vector<uint8_t> peaks;
  std::vector<uint8_t> keypoints;
};

// Encodes a landmark that passed Landmark::Validate(). Peaks and keypoints are written into
// `buffers` (replacing what they held); the descriptors are viewed in place. The result is valid
// while `landmark` and `buffers` are unchanged. num_descriptors is the number of keypoints.
EncodedLandmark EncodeLandmark(const Landmark& landmark, LandmarkBlobBuffers* buffers);

// Checks that the BLOB sizes agree with the encoding and with num_descriptors (which must be
// >= 0 and small enough that the sizes cannot overflow). The error message says what is wrong
// (e.g. "keypoints holds 3 bytes, 1 keypoints need 16") without naming the landmark: callers add
// that.
Status CheckLandmarkBlobs(const EncodedLandmark& encoded);

// Decodes a landmark whose BLOBs passed CheckLandmarkBlobs. Keypoints keep x, y, size and angle;
// the descriptors are a new CV_8U matrix of num_descriptors rows and kDescriptorSize columns.
Landmark DecodeLandmark(const EncodedLandmark& encoded);

}  // namespace placerec
