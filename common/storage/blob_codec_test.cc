#include "common/storage/blob_codec.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "common/storage/storage_testing.h"

namespace placerec {
namespace {

using testing_storage::ExpectSameLandmark;
using testing_storage::ExplicitLandmark;

std::vector<uint8_t> Bytes(const ByteView& view) {
  return std::vector<uint8_t>(view.data, view.data + view.size);
}

// Decodes `encoded` after checking it, as a store does.
Landmark CheckAndDecode(const EncodedLandmark& encoded) {
  const Status status = CheckLandmarkBlobs(encoded);
  EXPECT_TRUE(status.ok()) << status.ToString();
  return DecodeLandmark(encoded);
}

TEST(BlobCodecTest, FloatsAreStoredAsFloat32LittleEndian) {
  Landmark landmark;
  landmark.colour.peaks = {0.5f, -2.0f};
  landmark.descriptors = cv::Mat::zeros(1, 128, CV_8U);
  landmark.keypoints.emplace_back(1.0f, -2.0f, 0.25f, 90.0f);
  LandmarkBlobBuffers buffers;
  const EncodedLandmark encoded = EncodeLandmark(landmark, &buffers);
  EXPECT_EQ(Bytes(encoded.peaks), (std::vector<uint8_t>{0, 0, 0, 0x3f, 0, 0, 0, 0xc0}));
  EXPECT_EQ(Bytes(encoded.keypoints), (std::vector<uint8_t>{0, 0, 0x80, 0x3f, 0, 0, 0, 0xc0, 0, 0,
                                                            0x80, 0x3e, 0, 0, 0xb4, 0x42}));
  EXPECT_EQ(encoded.num_descriptors, 1);
  // The descriptors are the matrix's own bytes, not a copy.
  EXPECT_EQ(encoded.descriptors.data, landmark.descriptors.data);
  EXPECT_EQ(encoded.descriptors.size, 128u);
}

TEST(BlobCodecTest, RoundTripKeepsEveryStoredField) {
  LandmarkBlobBuffers buffers;
  for (int index = 0; index < 3; ++index) {
    SCOPED_TRACE(index);
    Landmark landmark = ExplicitLandmark(index);
    landmark.id = LandmarkId(40 + index);
    landmark.place = PlaceId(7);
    landmark.keypoints[0].response = 3.0f;  // not stored
    const Landmark decoded = CheckAndDecode(EncodeLandmark(landmark, &buffers));
    ExpectSameLandmark(landmark, decoded);
    for (size_t i = 0; i < decoded.keypoints.size(); ++i) {
      EXPECT_EQ(decoded.keypoints[i].response, 0.0f) << i;
    }
  }
}

TEST(BlobCodecTest, EmptyLandmarkRoundTripsWithEmptyBlobs) {
  LandmarkBlobBuffers buffers;
  buffers.peaks.assign(12, 1);  // left over from an earlier landmark
  const EncodedLandmark encoded = EncodeLandmark(Landmark(), &buffers);
  EXPECT_EQ(encoded.peaks.size, 0u);
  EXPECT_EQ(encoded.descriptors.data, nullptr);
  EXPECT_EQ(encoded.descriptors.size, 0u);
  EXPECT_EQ(encoded.keypoints.size, 0u);
  const Landmark decoded = CheckAndDecode(encoded);
  EXPECT_TRUE(decoded.colour.peaks.empty());
  EXPECT_EQ(decoded.descriptors.rows, 0);
  EXPECT_EQ(decoded.descriptors.cols, 128);
  EXPECT_TRUE(decoded.keypoints.empty());
}

TEST(BlobCodecTest, SpecialFloatsKeepTheirBits) {
  Landmark landmark;
  landmark.colour.peaks = {-0.0f, std::numeric_limits<float>::infinity(),
                           std::numeric_limits<float>::denorm_min()};
  LandmarkBlobBuffers buffers;
  const Landmark decoded = CheckAndDecode(EncodeLandmark(landmark, &buffers));
  ASSERT_EQ(decoded.colour.peaks.size(), 3u);
  EXPECT_TRUE(std::signbit(decoded.colour.peaks[0]));
  EXPECT_EQ(decoded.colour.peaks[1], std::numeric_limits<float>::infinity());
  EXPECT_EQ(decoded.colour.peaks[2], std::numeric_limits<float>::denorm_min());
}

TEST(BlobCodecTest, MalformedBlobsAreRejectedWithWhatIsWrong) {
  const Landmark landmark = ExplicitLandmark(0);  // 1 peak, 2 descriptors
  LandmarkBlobBuffers buffers;
  const EncodedLandmark good = EncodeLandmark(landmark, &buffers);
  ASSERT_TRUE(CheckLandmarkBlobs(good).ok());

  EncodedLandmark peaks = good;
  peaks.peaks.size = 5;
  EncodedLandmark descriptors = good;
  descriptors.descriptors.size = 10;
  EncodedLandmark keypoints = good;
  keypoints.keypoints.size = 3;
  EncodedLandmark count = good;  // one descriptor more than the BLOBs hold
  count.num_descriptors = 3;
  const struct {
    const EncodedLandmark& encoded;
    const char* message;
  } cases[] = {
      {peaks, "colour_peaks holds 5 bytes, not a multiple of 4"},
      {descriptors, "descriptors holds 10 bytes, 2 descriptors need 256"},
      {keypoints, "keypoints holds 3 bytes, 2 keypoints need 32"},
      {count, "descriptors holds 256 bytes, 3 descriptors need 384"},
  };
  for (const auto& c : cases) {
    const Status status = CheckLandmarkBlobs(c.encoded);
    EXPECT_EQ(status.code(), StatusCode::kIoError) << c.message;
    EXPECT_EQ(status.message(), c.message);
  }
}

}  // namespace
}  // namespace placerec
