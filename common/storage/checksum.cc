#include "common/storage/checksum.h"

#include <cstring>

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
  if (!place.seen_landmarks.empty()) {
    hash->Byte('S');
    hash->Int(static_cast<int64_t>(place.seen_landmarks.size()));
    for (const LandmarkId id : place.seen_landmarks) hash->Int(id.value());
  }
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
  if (!landmark.object_class.empty()) {
    hash->Byte('C');
    hash->Int(static_cast<int64_t>(landmark.object_class.size()));
    hash->Bytes(reinterpret_cast<const uint8_t*>(landmark.object_class.data()),
                landmark.object_class.size());
    uint32_t bits = 0;
    std::memcpy(&bits, &landmark.class_confidence, sizeof(bits));
    for (int i = 0; i < 4; ++i) hash->Byte(static_cast<uint8_t>(bits >> (8 * i)));
  }
}

}  // namespace placerec
