#include "common/recognition/types.h"

#include <gtest/gtest.h>

#include <limits>
#include <string>
#include <vector>

namespace placerec {
namespace {

Place ValidPlace() {
  Place place;
  place.robot = "r";
  place.image_width = 640;
  return place;
}

// A landmark with `rows` descriptors and as many keypoints.
Landmark ValidLandmark(int rows) {
  Landmark landmark;
  landmark.descriptors = cv::Mat::zeros(rows, 128, CV_8U);
  landmark.keypoints.resize(static_cast<size_t>(rows));
  landmark.box = cv::Rect(-5, 3, 10, 0);  // a box may start outside the frame and be empty
  return landmark;
}

void ExpectInvalid(const Status& status, const std::string& message) {
  EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(status.message(), message);
}

TEST(PlaceValidateTest, RobotIdAndImageWidth) {
  EXPECT_TRUE(ValidPlace().Validate().ok());
  Place longest = ValidPlace();
  longest.robot.assign(kMaxRobotIdLength, 'x');
  EXPECT_TRUE(longest.Validate().ok());

  Place place = ValidPlace();
  place.robot.clear();
  ExpectInvalid(place.Validate(), "robot id is empty");
  place = ValidPlace();
  place.robot.assign(kMaxRobotIdLength + 1, 'x');
  ExpectInvalid(place.Validate(), "robot id is 65 bytes, longer than the limit of 64");
  place = ValidPlace();
  place.robot = std::string("a\0b", 3);
  ExpectInvalid(place.Validate(), "robot id contains a NUL byte");
  place = ValidPlace();
  place.image_width = -1;
  ExpectInvalid(place.Validate(), "place image width is negative");
  // Capture times whose differences the map takes (vote windows, the recent past) stay far
  // from overflowing: 0 up to the end of the year 9999.
  place = ValidPlace();
  place.utime = kMaxUtime;
  EXPECT_TRUE(place.Validate().ok());
  place.utime = -1;
  ExpectInvalid(place.Validate(),
                "capture time -1 us is outside 0 .. 253402300799999999 (microseconds since the "
                "epoch, up to the end of the year 9999)");
  place.utime = std::numeric_limits<int64_t>::max();
  EXPECT_EQ(place.Validate().code(), StatusCode::kInvalidArgument);
  // The store sets ids and counts; they are not the caller's to get right.
  place = ValidPlace();
  place.id = PlaceId(-7);
  place.num_landmarks = -1;
  EXPECT_TRUE(place.Validate().ok());
}

TEST(LandmarkValidateTest, DescriptorsKeypointsAndFields) {
  EXPECT_TRUE(ValidLandmark(3).Validate().ok());
  EXPECT_TRUE(Landmark().Validate().ok());  // no descriptors at all

  Landmark landmark = ValidLandmark(3);
  landmark.descriptors.convertTo(landmark.descriptors, CV_32F);
  ExpectInvalid(landmark.Validate(), "descriptors must be CV_8U with one channel (type 5)");
  landmark = ValidLandmark(3);
  landmark.descriptors = cv::Mat::zeros(3, 128, CV_8UC2);
  ExpectInvalid(landmark.Validate(), "descriptors must be CV_8U with one channel (type 8)");
  landmark = ValidLandmark(3);
  landmark.descriptors = cv::Mat::zeros(3, 64, CV_8U);
  ExpectInvalid(landmark.Validate(), "descriptors have 64 columns, expected 128");
  landmark = ValidLandmark(3);
  const cv::Mat wide = cv::Mat::zeros(3, 256, CV_8U);
  landmark.descriptors = wide.colRange(0, 128);
  ExpectInvalid(landmark.Validate(), "descriptors are not continuous in memory");
  landmark = ValidLandmark(3);
  landmark.keypoints.pop_back();
  ExpectInvalid(landmark.Validate(),
                "2 keypoints for 3 descriptors; there must be one per descriptor");
  landmark = Landmark();
  landmark.keypoints.resize(1);
  ExpectInvalid(landmark.Validate(),
                "1 keypoints for 0 descriptors; there must be one per descriptor");
  landmark = ValidLandmark(3);
  landmark.sift_count = -2;
  ExpectInvalid(landmark.Validate(), "sift_count is negative (-2)");
  landmark = ValidLandmark(3);
  landmark.segment_class = static_cast<SegmentClass>(5);
  ExpectInvalid(landmark.Validate(), "unknown segment class 5");
  landmark = ValidLandmark(3);
  landmark.box.height = -1;
  ExpectInvalid(landmark.Validate(), "box has a negative size");
}

TEST(ValidatePlaceAndLandmarksTest, PlaceFirstThenLandmarksByIndex) {
  std::vector<Landmark> landmarks = {ValidLandmark(2), ValidLandmark(0), ValidLandmark(4)};
  EXPECT_TRUE(ValidatePlaceAndLandmarks(ValidPlace(), landmarks).ok());
  EXPECT_TRUE(ValidatePlaceAndLandmarks(ValidPlace(), {}).ok());

  landmarks[1].sift_count = -1;
  landmarks[2].sift_count = -1;
  ExpectInvalid(ValidatePlaceAndLandmarks(ValidPlace(), landmarks),
                "landmark 1: sift_count is negative (-1)");
  Place place = ValidPlace();
  place.robot.clear();
  ExpectInvalid(ValidatePlaceAndLandmarks(place, landmarks), "robot id is empty");
}

}  // namespace
}  // namespace placerec
