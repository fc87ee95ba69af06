// The map digest behind LandmarkStore::Checksum(): FNV-1a 64 over a canonical serialization of
// every place and landmark in id order. Any store that hashes its contents with these functions
// gives equal digests for equal maps, whatever the database.
#pragma once

#include <cstddef>
#include <cstdint>

#include "common/recognition/types.h"
#include "common/storage/blob_codec.h"

namespace placerec {

// FNV-1a, 64 bits (offset basis 14695981039346656037, prime 1099511628211).
class Fnv1a64 {
 public:
  void Bytes(const uint8_t* data, size_t size) {
    for (size_t i = 0; i < size; ++i) {
      hash_ ^= data[i];
      hash_ *= 1099511628211ULL;
    }
  }
  void Byte(uint8_t value) { Bytes(&value, 1); }
  // Every integer enters as 8 bytes, little-endian, whatever its C++ type.
  void Int(int64_t value) {
    uint8_t bytes[8];
    for (int i = 0; i < 8; ++i) {
      bytes[i] = static_cast<uint8_t>(static_cast<uint64_t>(value) >> (8 * i));
    }
    Bytes(bytes, sizeof(bytes));
  }
  uint64_t digest() const { return hash_; }

 private:
  uint64_t hash_ = 14695981039346656037ULL;
};

// Tag 'P', then id, robot length, robot bytes, sequence, utime, num_landmarks, image_width; then,
// only for a place that saw stored landmarks again (schema v2), tag 'S', their number and ids.
void HashPlace(const Place& place, Fnv1a64* hash);

// Tag 'L', then id, place, sift_count, number of peaks, the peaks (float32 LE), segment class,
// box x, y, w, h, number of descriptors, the descriptor bytes, the keypoints (x, y, size, angle
// as float32 LE); then, only for a classified landmark (schema v2), tag 'C', the class name's
// length and bytes and the confidence (float32 LE), so that a map without classes keeps the
// digest it had under schema v1. Integers are 8 bytes LE. The stored BLOBs are already in this
// form, so they are hashed as stored; `landmark` must have passed CheckLandmarkBlobs.
void HashLandmark(const EncodedLandmark& landmark, Fnv1a64* hash);

}  // namespace placerec
