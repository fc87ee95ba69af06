// Checks the lengths a received LCM message claims before lcm-gen's decoder trusts them. The
// decoder resizes an array to the count it reads before it checks that the elements are there,
// so a message of a hundred bytes that claims 2^31 - 1 elements made a receiver allocate
// gigabytes. These walks follow the layouts in proto/*.lcm (fields in declaration order, nested
// structs without their fingerprint, strings as an int32 length with the NUL, then the bytes)
// and fail when a count is negative or its elements cannot fit in the bytes left.
#pragma once

#include <cstddef>
#include <cstdint>

#include "placerec/change_t.hpp"
#include "placerec/result_t.hpp"
#include "placerec/status_t.hpp"

namespace placerec {
namespace wire {

// A cursor over the message's bytes; once a read fails, every later one fails too.
class Reader {
 public:
  Reader(const void* data, size_t size) : data_(static_cast<const uint8_t*>(data)), size_(size) {}

  bool ok() const { return ok_; }
  size_t left() const { return ok_ ? size_ - at_ : 0; }

  void Skip(size_t bytes) {
    if (!ok_ || bytes > size_ - at_) {
      ok_ = false;
      return;
    }
    at_ += bytes;
  }

  int32_t Int32() {
    if (!ok_ || size_ - at_ < 4) {
      ok_ = false;
      return 0;
    }
    const uint32_t v = (uint32_t{data_[at_]} << 24) | (uint32_t{data_[at_ + 1]} << 16) |
                       (uint32_t{data_[at_ + 2]} << 8) | uint32_t{data_[at_ + 3]};
    at_ += 4;
    return static_cast<int32_t>(v);
  }

  void String() {
    const int32_t length = Int32();
    if (length < 1) ok_ = false;  // at least the NUL
    Skip(ok_ ? static_cast<size_t>(length) : 0);
  }

  // A count read before its array: false (and failed) when `count` elements of at least
  // `min_bytes` each cannot fit in what is left.
  bool Count(int32_t count, size_t min_bytes) {
    if (!ok_ || count < 0 || static_cast<size_t>(count) > left() / min_bytes) ok_ = false;
    return ok_;
  }

 private:
  const uint8_t* data_;
  size_t size_;
  size_t at_ = 8;  // after the fingerprint
  bool ok_ = true;
};

constexpr size_t kMinStringBytes = 4 + 1;

inline void WalkMatch(Reader* r) {
  r->Skip(8);                      // utime
  r->String();                     // robot
  r->Skip(8 + 8 + 8 + 4 + 4 + 4);  // sequence, place_id, score, three counts
  const int32_t classes = r->Int32();
  if (!r->Count(classes, kMinStringBytes)) return;
  for (int32_t i = 0; i < classes && r->ok(); ++i) r->String();
  if (r->Count(classes, 4)) r->Skip(4 * static_cast<size_t>(classes));  // class_counts
}

// Whether every length in a result_t's bytes fits (proto/result_t.lcm, match_t, stage_time_t).
inline bool LengthsFit(const void* data, size_t size, const result_t*) {
  Reader r(data, size);
  r.Skip(8);                  // utime
  r.String();                 // robot
  r.Skip(8 + 8 + 8 + 1 + 1);  // sequence, request_id, frame_utime, insert, status
  r.String();                 // message
  r.Skip(1);                  // loop_closure
  const int32_t matches = r.Int32();
  // A match takes at least its fixed fields, a robot id and a class count.
  if (!r.Count(matches, 8 + kMinStringBytes + 40)) return false;
  for (int32_t i = 0; i < matches && r.ok(); ++i) WalkMatch(&r);
  r.Skip(4 * 4 + 8 * 4 + 8 * 2);  // keypoints .. stored_descriptors, place_id .. map_descriptors,
                                  // queue_ms, server_ms
  const int32_t timings = r.Int32();
  if (!r.Count(timings, kMinStringBytes + 8)) return false;
  for (int32_t i = 0; i < timings && r.ok(); ++i) {
    r.String();  // stage
    r.Skip(8);   // ms
  }
  r.String();          // key_id
  r.Skip(32 + 1 + 8);  // signature, change_checked, change_place_id
  const int32_t changes = r.Int32();
  // kinds (1 byte), boxes (16), classes (a string), confidences (4) per change.
  if (!r.Count(changes, 1 + 16 + kMinStringBytes + 4)) return false;
  r.Skip(static_cast<size_t>(changes) * (1 + 16));
  for (int32_t i = 0; i < changes && r.ok(); ++i) r.String();
  r.Skip(static_cast<size_t>(changes) * 4);
  r.Skip(8);  // next_sequence
  return r.ok();
}

// Whether every length in a change_t's bytes fits (proto/change_t.lcm).
inline bool LengthsFit(const void* data, size_t size, const change_t*) {
  Reader r(data, size);
  r.Skip(8);                       // utime
  r.String();                      // robot
  r.Skip(8 + 8 + 8 + 8);           // sequence, request_id, frame_utime, place_id
  r.String();                      // place_robot
  r.Skip(8 + 8 + 4 + 4 + 1 + 16);  // place_sequence .. kind, box
  r.String();                      // object_class
  r.Skip(4 + 4 + 4);               // confidence, frame_width, frame_height
  const int32_t frame_jpeg = r.Int32();
  if (!r.Count(frame_jpeg, 1)) return false;
  r.Skip(static_cast<size_t>(frame_jpeg));
  const int32_t place_jpeg = r.Int32();
  if (!r.Count(place_jpeg, 1)) return false;
  r.Skip(static_cast<size_t>(place_jpeg));
  return r.ok();
}

// status_t has no arrays; its strings' lengths are checked by the decoder itself.
inline bool LengthsFit(const void*, size_t, const status_t*) { return true; }

}  // namespace wire
}  // namespace placerec
