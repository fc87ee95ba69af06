#include "common/recognition/types.h"

#include <cctype>
#include <climits>
#include <cmath>
#include <string>

#include "common/features/features.h"

namespace placerec {

Status CheckCaptureTime(int64_t utime) {
  if (utime >= 0 && utime <= kMaxUtime) return Status::Ok();
  return Status::InvalidArgument("capture time " + std::to_string(utime) + " us is outside 0 .. " +
                                 std::to_string(kMaxUtime) +
                                 " (microseconds since the epoch, up to the end of the year 9999)");
}

Status Place::Validate() const {
  if (robot.empty()) return Status::InvalidArgument("robot id is empty");
  if (image_width < 0) return Status::InvalidArgument("place image width is negative");
  if (Status time = CheckCaptureTime(utime); !time.ok()) return time;
  if (robot.size() > kMaxRobotIdLength) {
    return Status::InvalidArgument("robot id is " + std::to_string(robot.size()) +
                                   " bytes, longer than the limit of " +
                                   std::to_string(kMaxRobotIdLength));
  }
  if (robot.find('\0') != std::string::npos) {
    return Status::InvalidArgument("robot id contains a NUL byte");
  }
  if (thumbnail.size() > kMaxThumbnailBytes) {
    return Status::InvalidArgument("place thumbnail is " + std::to_string(thumbnail.size()) +
                                   " bytes, more than the limit of " +
                                   std::to_string(kMaxThumbnailBytes));
  }
  for (size_t i = 0; i < seen_landmarks.size(); ++i) {
    if (!seen_landmarks[i].IsValid() || (i > 0 && !(seen_landmarks[i - 1] < seen_landmarks[i]))) {
      return Status::InvalidArgument("seen landmarks must be valid ids, increasing");
    }
  }
  return Status::Ok();
}

Status Landmark::Validate() const {
  if (!descriptors.empty()) {
    if (descriptors.type() != CV_8UC1) {
      return Status::InvalidArgument("descriptors must be CV_8U with one channel (type " +
                                     std::to_string(descriptors.type()) + ")");
    }
    if (descriptors.dims != 2 || descriptors.cols != kDescriptorSize) {
      return Status::InvalidArgument("descriptors have " + std::to_string(descriptors.cols) +
                                     " columns, expected " + std::to_string(kDescriptorSize));
    }
    if (!descriptors.isContinuous()) {
      return Status::InvalidArgument("descriptors are not continuous in memory");
    }
  }
  const size_t rows = descriptors.empty() ? 0 : static_cast<size_t>(descriptors.rows);
  if (keypoints.size() != rows) {
    return Status::InvalidArgument(std::to_string(keypoints.size()) + " keypoints for " +
                                   std::to_string(rows) +
                                   " descriptors; there must be one per descriptor");
  }
  for (size_t i = 0; i < keypoints.size(); ++i) {
    const cv::KeyPoint& k = keypoints[i];
    if (!std::isfinite(k.pt.x) || !std::isfinite(k.pt.y) || !std::isfinite(k.size) ||
        !std::isfinite(k.angle)) {
      return Status::InvalidArgument("keypoint " + std::to_string(i) +
                                     " has a position, size or angle that is not a finite number");
    }
  }
  if (sift_count < 0) {
    return Status::InvalidArgument("sift_count is negative (" + std::to_string(sift_count) + ")");
  }
  if (!IsKnownSegmentClass(static_cast<int>(segment_class))) {
    return Status::InvalidArgument("unknown segment class " +
                                   std::to_string(static_cast<int>(segment_class)));
  }
  if (box.width < 0 || box.height < 0) return Status::InvalidArgument("box has a negative size");
  if (object_class.size() > kMaxObjectClassLength) {
    return Status::InvalidArgument("object class is " + std::to_string(object_class.size()) +
                                   " bytes; the limit is " + std::to_string(kMaxObjectClassLength));
  }
  for (unsigned char c : object_class) {
    if (!((c < 0x80 && std::isalnum(c)) || c == '_' || c == '-')) {
      return Status::InvalidArgument(
          "object class may hold only ASCII letters, digits, '_' and '-'");
    }
  }
  if (!(class_confidence >= 0.0f && class_confidence <= 1.0f) ||
      (object_class.empty() && class_confidence != 0.0f)) {
    return Status::InvalidArgument("class confidence must be in [0, 1], and 0 without a class");
  }
  return Status::Ok();
}

Status ValidatePlaceAndLandmarks(const Place& place, const std::vector<Landmark>& landmarks) {
  PLACEREC_RETURN_IF_ERROR(place.Validate());
  if (landmarks.size() > static_cast<size_t>(INT_MAX)) {
    return Status::InvalidArgument("too many landmarks for one place");
  }
  for (size_t i = 0; i < landmarks.size(); ++i) {
    const Status status = landmarks[i].Validate();
    if (!status.ok()) {
      return Status::InvalidArgument("landmark " + std::to_string(i) + ": " + status.message());
    }
  }
  return Status::Ok();
}

}  // namespace placerec
