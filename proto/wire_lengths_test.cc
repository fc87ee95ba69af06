// Decoding received messages without trusting their lengths (proto/wire_lengths.h): genuine
// messages of every kind decode whole, and one whose count claims more elements than its bytes
// hold is refused before lcm-gen's decoder sizes an array by it (it used to allocate gigabytes).
#include "proto/wire_lengths.h"

#include <gtest/gtest.h>

#include <cstring>
#include <vector>

#include "proto/decode.h"

namespace placerec {
namespace {

template <typename Message>
std::vector<uint8_t> Encode(const Message& message) {
  std::vector<uint8_t> bytes(message.getEncodedSize());
  EXPECT_EQ(message.encode(bytes.data(), 0, static_cast<int>(bytes.size())),
            static_cast<int>(bytes.size()));
  return bytes;
}

// Overwrites the big-endian int32 at `offset`.
void PutInt32(std::vector<uint8_t>* bytes, size_t offset, int32_t value) {
  const uint32_t v = static_cast<uint32_t>(value);
  for (int i = 0; i < 4; ++i) (*bytes)[offset + i] = static_cast<uint8_t>(v >> (24 - 8 * i));
}

result_t FullResult() {
  result_t r{};
  r.robot = "r1";
  r.message = "ok";
  r.num_matches = 2;
  r.matches.resize(2);
  for (match_t& m : r.matches) {
    m.robot = "left";
    m.num_classes = 2;
    m.classes = {"building", "sign"};
    m.class_counts = {3, 1};
  }
  r.num_timings = 1;
  r.timings.resize(1);
  r.timings[0].stage = "sift";
  r.key_id = "key";
  r.num_changes = 2;
  r.change_kinds = {0, 1};
  r.change_boxes = {{1, 2, 3, 4}, {5, 6, 7, 8}};
  r.change_classes = {"car", ""};
  r.change_confidences = {0.5f, 0.25f};
  return r;
}

change_t FullChange() {
  change_t c{};
  c.robot = "r1";
  c.place_robot = "r2";
  c.object_class = "car";
  c.frame_jpeg_size = 3;
  c.frame_jpeg = {1, 2, 3};
  c.place_jpeg_size = 2;
  c.place_jpeg = {4, 5};
  return c;
}

TEST(WireLengthsTest, GenuineMessagesDecodeWhole) {
  const std::vector<uint8_t> result = Encode(FullResult());
  result_t decoded_result;
  ASSERT_TRUE(DecodeLcmMessage(result.data(), result.size(), &decoded_result));
  EXPECT_EQ(decoded_result.matches[1].classes[1], "sign");
  EXPECT_EQ(decoded_result.change_classes[0], "car");
  EXPECT_EQ(decoded_result.change_confidences[1], 0.25f);

  const std::vector<uint8_t> change = Encode(FullChange());
  change_t decoded_change;
  ASSERT_TRUE(DecodeLcmMessage(change.data(), change.size(), &decoded_change));
  EXPECT_EQ(decoded_change.place_jpeg, (std::vector<uint8_t>{4, 5}));

  status_t status{};
  status.version = "v";
  status.map = "sqlite:x";
  const std::vector<uint8_t> status_bytes = Encode(status);
  status_t decoded_status;
  EXPECT_TRUE(DecodeLcmMessage(status_bytes.data(), status_bytes.size(), &decoded_status));
}

TEST(WireLengthsTest, EveryCutOfAGenuineMessageIsRefused) {
  const std::vector<uint8_t> result = Encode(FullResult());
  for (size_t size = 0; size < result.size(); ++size) {
    result_t decoded;
    EXPECT_FALSE(DecodeLcmMessage(result.data(), size, &decoded)) << size;
  }
  const std::vector<uint8_t> change = Encode(FullChange());
  for (size_t size = 0; size < change.size(); ++size) {
    change_t decoded;
    EXPECT_FALSE(DecodeLcmMessage(change.data(), size, &decoded)) << size;
  }
}

// The count of each array, forged to 2^31 - 1 (or -1), is refused by the walk itself.
TEST(WireLengthsTest, ACountBeyondTheMessageIsRefusedBeforeDecoding) {
  // change_t: frame_jpeg_size comes 4 + 3 + 4 + 2 + ... bytes in; find it by its value.
  const change_t change = FullChange();
  const std::vector<uint8_t> genuine = Encode(change);
  // The frame picture's size is the int32 3 followed by the bytes 1, 2, 3.
  size_t frame_size_at = 0;
  for (size_t i = 8; i + 7 <= genuine.size(); ++i) {
    if (std::memcmp(genuine.data() + i, "\0\0\0\3\1\2\3", 7) == 0) frame_size_at = i;
  }
  ASSERT_GT(frame_size_at, 0u);
  for (const int32_t forged : {INT32_MAX, -1, 4}) {
    std::vector<uint8_t> bytes = genuine;
    PutInt32(&bytes, frame_size_at, forged);
    EXPECT_FALSE(wire::LengthsFit(bytes.data(), bytes.size(), &change)) << forged;
    change_t decoded;
    EXPECT_FALSE(DecodeLcmMessage(bytes.data(), bytes.size(), &decoded)) << forged;
  }

  // result_t: num_changes is the int32 2 right after the change place id; num_matches right
  // after the loop_closure byte.
  result_t r = FullResult();
  r.change_place_id = 0x0102030405060708;
  const std::vector<uint8_t> result = Encode(r);
  const uint8_t marker[] = {1, 2, 3, 4, 5, 6, 7, 8, 0, 0, 0, 2};
  size_t changes_at = 0;
  for (size_t i = 8; i + sizeof(marker) <= result.size(); ++i) {
    if (std::memcmp(result.data() + i, marker, sizeof(marker)) == 0) changes_at = i + 8;
  }
  ASSERT_GT(changes_at, 0u);
  for (const int32_t forged : {INT32_MAX, -1, 3}) {
    std::vector<uint8_t> bytes = result;
    PutInt32(&bytes, changes_at, forged);
    EXPECT_FALSE(wire::LengthsFit(bytes.data(), bytes.size(), &r)) << forged;
  }
  // num_matches: after fingerprint, utime, robot ("r1": length 3), sequence, request_id,
  // frame_utime, insert, status, message ("ok": length 3), loop_closure.
  const size_t matches_at = 8 + 8 + 4 + 3 + 8 + 8 + 8 + 1 + 1 + 4 + 3 + 1;
  std::vector<uint8_t> bytes = result;
  ASSERT_EQ(bytes[matches_at + 3], 2);
  PutInt32(&bytes, matches_at, INT32_MAX);
  EXPECT_FALSE(wire::LengthsFit(bytes.data(), bytes.size(), &r));
}

}  // namespace
}  // namespace placerec
