#include "common/storage/checksum.h"

namespace placerec {

void HashPlace(const Place& place, Fnv1a64* hash) {
  hash->Byte('P');
  hash->Int(place.id.value());
  hash->Int(static_cast<int64_t>(place.robot.size()));
  hash->Bytes(reinterpret_cast<const uint8_t*>(place.robot.data()), place.robot.size());
  hash->Int(place.sequence);
  hash->Int(place.utime);
  hash->Int(place.num_landmarks);
  hash->Int(place.image_width);
}

void HashLandmark(const EncodedLandmark& landmark, Fnv1a64* hash) {
  hash->Byte('L');
  hash->Int(landmark.id);
  hash->Int(landmark.place);
  hash->Int(landmark.sift_count);
  hash->Int(static_cast<int64_t>(landmark.peaks.size / kPeakBytes));
  hash->Bytes(landmark.peaks.data, landmark.peaks.size);
  hash->Int(landmark.segment_class);
  for (int64_t value : landmark.box) hash->Int(value);
  hash->Int(landmark.num_descriptors);
  hash->Bytes(landmark.descriptors.data, landmark.descriptors.size);
  hash->Bytes(landmark.keypoints.data, landmark.keypoints.size);
}

}  // namespace placerec
