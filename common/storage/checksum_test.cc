#include "common/storage/checksum.h"

#include <gtest/gtest.h>

#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "common/storage/sqlite_store.h"
#include "common/storage/storage_testing.h"

namespace placerec {
namespace {

using testing_storage::ExplicitLandmark;

uint64_t HashOfText(const std::string& text) {
  Fnv1a64 hash;
  hash.Bytes(reinterpret_cast<const uint8_t*>(text.data()), text.size());
  return hash.digest();
}

TEST(Fnv1a64Test, MatchesTheReferenceVectors) {
  EXPECT_EQ(HashOfText(""), 0xcbf29ce484222325u);
  EXPECT_EQ(HashOfText("a"), 0xaf63dc4c8601ec8cu);
  EXPECT_EQ(HashOfText("foobar"), 0x85944171f73967e8u);
}

TEST(Fnv1a64Test, IntegersEnterAsEightBytesLittleEndian) {
  const struct {
    int64_t value;
    std::vector<uint8_t> bytes;
  } cases[] = {
      {0x0102030405060708, {8, 7, 6, 5, 4, 3, 2, 1}},
      {-1, {0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff}},
      {7, {7, 0, 0, 0, 0, 0, 0, 0}},
  };
  for (const auto& c : cases) {
    Fnv1a64 as_int;
    as_int.Int(c.value);
    Fnv1a64 as_bytes;
    as_bytes.Bytes(c.bytes.data(), c.bytes.size());
    EXPECT_EQ(as_int.digest(), as_bytes.digest()) << c.value;
  }
  Fnv1a64 as_byte;
  as_byte.Byte('a');
  EXPECT_EQ(as_byte.digest(), HashOfText("a"));
}

TEST(MapHashTest, PlaceIsHashedInItsCanonicalSerialization) {
  Place place;
  place.id = PlaceId(3);
  place.robot = "r2";
  place.sequence = -4;
  place.utime = 1700000000000000;
  place.num_landmarks = 5;
  place.image_width = 640;
  Fnv1a64 hash;
  HashPlace(place, &hash);

  Fnv1a64 expected;
  expected.Byte('P');
  for (int64_t value : {int64_t{3}, int64_t{2}}) expected.Int(value);
  expected.Bytes(reinterpret_cast<const uint8_t*>("r2"), 2);
  for (int64_t value : {int64_t{-4}, int64_t{1700000000000000}, int64_t{5}, int64_t{640}}) {
    expected.Int(value);
  }
  EXPECT_EQ(hash.digest(), expected.digest());
}

TEST(MapHashTest, EveryLandmarkFieldCounts) {
  const Landmark landmark = ExplicitLandmark(1);
  LandmarkBlobBuffers buffers;
  const EncodedLandmark base = EncodeLandmark(landmark, &buffers);
  const auto digest = [](const EncodedLandmark& encoded) {
    Fnv1a64 hash;
    HashLandmark(encoded, &hash);
    return hash.digest();
  };
  const uint64_t base_digest = digest(base);
  std::vector<EncodedLandmark> changed(11, base);
  changed[0].id += 1;
  changed[1].place += 1;
  changed[2].sift_count += 1;
  changed[3].segment_class = 0;
  for (int k = 0; k < 4; ++k) changed[4 + static_cast<size_t>(k)].box[k] += 1;
  // Fewer bytes in one BLOB: the counts before the BLOBs keep their boundaries apart.
  changed[8].peaks.size -= kPeakBytes;
  changed[9].keypoints.size -= kKeypointBytes;
  const std::vector<uint8_t> other_row(128, 0);
  changed[10].descriptors.data = other_row.data();
  changed[10].descriptors.size = other_row.size();
  changed[10].num_descriptors = 1;
  for (size_t i = 0; i < changed.size(); ++i) EXPECT_NE(digest(changed[i]), base_digest) << i;
}

// A class enters the digest; its absence leaves the schema v1 digest (pinned below) as it was.
TEST(MapHashTest, ObjectClassCountsOnlyWhenPresent) {
  Landmark landmark = ExplicitLandmark(1);
  LandmarkBlobBuffers buffers;
  const auto digest = [&buffers](const Landmark& l) {
    Fnv1a64 hash;
    HashLandmark(EncodeLandmark(l, &buffers), &hash);
    return hash.digest();
  };
  const uint64_t unclassified = digest(landmark);
  landmark.object_class = "building";
  landmark.class_confidence = 0.75f;
  const uint64_t building = digest(landmark);
  EXPECT_NE(building, unclassified);
  landmark.class_confidence = 0.5f;
  EXPECT_NE(digest(landmark), building);
  landmark.class_confidence = 0.75f;
  landmark.object_class = "buildinh";
  EXPECT_NE(digest(landmark), building);
}

// The checksum of a fixed map is pinned: it is a persisted fingerprint (maps are compared by it
// across builds), and since it hashes the stored BLOBs as they are, it also pins their encoding.
// Everything below is explicit (no random numbers), so the value depends on nothing else.
TEST(MapHashTest, ChecksumOfAFixedMapIsPinned) {
  StatusOr<std::unique_ptr<LandmarkStore>> store =
      OpenSqliteStore(":memory:", SqliteStoreOptions());
  ASSERT_TRUE(store.ok()) << store.status().ToString();
  StatusOr<uint64_t> checksum = (*store)->Checksum();
  ASSERT_TRUE(checksum.ok()) << checksum.status().ToString();
  EXPECT_EQ(*checksum, 0xcbf29ce484222325u);  // FNV-1a 64 offset basis: nothing hashed
  for (int sequence = 0; sequence < 3; ++sequence) {
    Place place;
    place.robot = sequence == 1 ? "beta" : "alpha";
    place.sequence = sequence;
    place.utime = 1700000000000000 + sequence * 100000;
    place.image_width = 640 + sequence % 3;
    std::vector<Landmark> landmarks;
    for (int i = 0; i < sequence; ++i) landmarks.push_back(ExplicitLandmark(i));
    ASSERT_TRUE((*store)->AddPlace(&place, &landmarks).ok());
  }
  checksum = (*store)->Checksum();
  ASSERT_TRUE(checksum.ok()) << checksum.status().ToString();
  EXPECT_EQ(*checksum, 0x33ebd2cf9988439bu);  // the value of the code before it was split
}

}  // namespace
}  // namespace placerec
