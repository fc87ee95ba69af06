#include "common/storage/blob_codec.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "common/features/features.h"

namespace placerec {
namespace {

static_assert(sizeof(float) == 4 && std::numeric_limits<float>::is_iec559,
              "the BLOB formats store IEEE-754 float32");

void AppendFloat(float value, std::vector<uint8_t>* out) {
  uint32_t bits = 0;
  std::memcpy(&bits, &value, sizeof(bits));
  for (int shift = 0; shift < 32; shift += 8) out->push_back(static_cast<uint8_t>(bits >> shift));
}

float ReadFloat(const uint8_t* bytes) {
  const uint32_t bits = static_cast<uint32_t>(bytes[0]) | static_cast<uint32_t>(bytes[1]) << 8 |
                        static_cast<uint32_t>(bytes[2]) << 16 |
                        static_cast<uint32_t>(bytes[3]) << 24;
  float value = 0;
  std::memcpy(&value, &bits, sizeof(value));
  return value;
}

void EncodePeaks(const ColourSignature& colour, std::vector<uint8_t>* out) {
  out->clear();
  for (float peak : colour.peaks) AppendFloat(peak, out);
}

void EncodeKeypoints(const std::vector<cv::KeyPoint>& keypoints, std::vector<uint8_t>* out) {
  out->clear();
  for (const cv::KeyPoint& keypoint : keypoints) {
    AppendFloat(keypoint.pt.x, out);
    AppendFloat(keypoint.pt.y, out);
    AppendFloat(keypoint.size, out);
    AppendFloat(keypoint.angle, out);
  }
}

}  // namespace

EncodedLandmark EncodeLandmark(const Landmark& landmark, LandmarkBlobBuffers* buffers) {
  EncodePeaks(landmark.colour, &buffers->peaks);
  EncodeKeypoints(landmark.keypoints, &buffers->keypoints);
  const size_t num_descriptors = landmark.keypoints.size();  // == rows, validated
  EncodedLandmark encoded;
  encoded.id = landmark.id.value();
  encoded.place = landmark.place.value();
  encoded.sift_count = landmark.sift_count;
  encoded.peaks = {buffers->peaks.data(), buffers->peaks.size()};
  encoded.segment_class = static_cast<int64_t>(landmark.segment_class);
  encoded.box[0] = landmark.box.x;
  encoded.box[1] = landmark.box.y;
  encoded.box[2] = landmark.box.width;
  encoded.box[3] = landmark.box.height;
  encoded.num_descriptors = static_cast<int64_t>(num_descriptors);
  encoded.descriptors = {num_descriptors > 0 ? landmark.descriptors.data : nullptr,
                         num_descriptors * kDescriptorSize};
  encoded.keypoints = {buffers->keypoints.data(), buffers->keypoints.size()};
  encoded.object_class = landmark.object_class;
  encoded.class_confidence = landmark.class_confidence;
  return encoded;
}

Status CheckLandmarkBlobs(const EncodedLandmark& encoded) {
  if (encoded.peaks.size % kPeakBytes != 0) {
    return Status::IoError("colour_peaks holds " + std::to_string(encoded.peaks.size) +
                           " bytes, not a multiple of " + std::to_string(kPeakBytes));
  }
  const size_t n = static_cast<size_t>(encoded.num_descriptors);
  if (encoded.descriptors.size != n * kDescriptorSize) {
    return Status::IoError("descriptors holds " + std::to_string(encoded.descriptors.size) +
                           " bytes, " + std::to_string(n) + " descriptors need " +
                           std::to_string(n * kDescriptorSize));
  }
  if (encoded.keypoints.size != n * kKeypointBytes) {
    return Status::IoError("keypoints holds " + std::to_string(encoded.keypoints.size) +
                           " bytes, " + std::to_string(n) + " keypoints need " +
                           std::to_string(n * kKeypointBytes));
  }
  // x, y, size and angle: a NaN angle would index outside the orientation histogram of matching.
  for (size_t i = 0; i < n * kKeypointBytes; i += 4) {
    if (!std::isfinite(ReadFloat(encoded.keypoints.data + i))) {
      return Status::IoError("keypoint " + std::to_string(i / kKeypointBytes) +
                             " holds a value that is not a finite number");
    }
  }
  return Status::Ok();
}

Landmark DecodeLandmark(const EncodedLandmark& encoded) {
  Landmark landmark;
  landmark.id = LandmarkId(encoded.id);
  landmark.place = PlaceId(encoded.place);
  landmark.sift_count = static_cast<int>(encoded.sift_count);
  const size_t num_peaks = encoded.peaks.size / kPeakBytes;
  landmark.colour.peaks.resize(num_peaks);
  for (size_t i = 0; i < num_peaks; ++i) {
    landmark.colour.peaks[i] = ReadFloat(encoded.peaks.data + i * kPeakBytes);
  }
  landmark.segment_class = static_cast<SegmentClass>(encoded.segment_class);
  landmark.box = cv::Rect(static_cast<int>(encoded.box[0]), static_cast<int>(encoded.box[1]),
                          static_cast<int>(encoded.box[2]), static_cast<int>(encoded.box[3]));
  const int n = static_cast<int>(encoded.num_descriptors);
  landmark.descriptors.create(n, kDescriptorSize, CV_8U);
  if (n > 0) {
    std::memcpy(landmark.descriptors.data, encoded.descriptors.data, encoded.descriptors.size);
  }
  landmark.keypoints.resize(n);
  for (int i = 0; i < n; ++i) {
    const uint8_t* bytes = encoded.keypoints.data + static_cast<size_t>(i) * kKeypointBytes;
    landmark.keypoints[i] = cv::KeyPoint(ReadFloat(bytes), ReadFloat(bytes + 4),
                                         ReadFloat(bytes + 8), ReadFloat(bytes + 12));
  }
  landmark.object_class = encoded.object_class;
  landmark.class_confidence = encoded.class_confidence;
  return landmark;
}

}  // namespace placerec
