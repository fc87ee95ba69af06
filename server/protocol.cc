#include "server/protocol.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <exception>

#include "proto/auth/signing.h"
#include "proto/channels.h"

namespace placerec {
namespace {

// Where frame_t's robot id (its int32 length) starts: after fingerprint, utime, sequence,
// request_id, insert, encoding, width and height (proto/frame_t.lcm).
constexpr size_t kRobotLengthOffset = 8 + 8 + 8 + 8 + 1 + 1 + 4 + 4;

// Reads a big-endian int32 (LCM's wire order) at `offset`; false when it does not fit.
bool ReadInt32(const uint8_t* data, size_t size, size_t offset, int32_t* value) {
  if (offset + 4 > size) return false;
  const uint32_t v = (static_cast<uint32_t>(data[offset]) << 24) |
                     (static_cast<uint32_t>(data[offset + 1]) << 16) |
                     (static_cast<uint32_t>(data[offset + 2]) << 8) |
                     static_cast<uint32_t>(data[offset + 3]);
  *value = static_cast<int32_t>(v);
  return true;
}

// The code lcm-gen writes resizes strings and arrays to the length a message claims before it
// checks that the bytes are there, so a forged length would make it allocate gigabytes or throw.
// This walks frame_t's layout (fingerprint, utime, sequence, request_id, insert, encoding, width,
// height, robot, key_id, auth_counter, auth_utime, signature[32], size, data; see
// proto/frame_t.lcm) and checks the three lengths first.
Status CheckFrameLengths(const uint8_t* data, size_t size) {
  int32_t robot_length = 0;
  if (!ReadInt32(data, size, kRobotLengthOffset, &robot_length)) {
    return Status::InvalidArgument("message of " + std::to_string(size) +
                                   " bytes is too short for a frame");
  }
  const size_t robot_begin = kRobotLengthOffset + 4;
  if (robot_length < 1 || static_cast<size_t>(robot_length) > size - robot_begin) {
    return Status::InvalidArgument("robot id length " + std::to_string(robot_length) +
                                   " does not fit the message");
  }
  const size_t key_id_offset = robot_begin + static_cast<size_t>(robot_length);
  int32_t key_id_length = 0;
  if (!ReadInt32(data, size, key_id_offset, &key_id_length)) {
    return Status::InvalidArgument("message ends before the key id");
  }
  const size_t key_id_begin = key_id_offset + 4;
  if (key_id_length < 1 || static_cast<size_t>(key_id_length) > size - key_id_begin) {
    return Status::InvalidArgument("key id length " + std::to_string(key_id_length) +
                                   " does not fit the message");
  }
  // auth_counter, auth_utime and the signature have fixed sizes.
  const size_t size_offset = key_id_begin + static_cast<size_t>(key_id_length) + 8 + 8 + 32;
  int32_t data_size = 0;
  if (!ReadInt32(data, size, size_offset, &data_size)) {
    return Status::InvalidArgument("message ends before the image size");
  }
  if (data_size < 0 || static_cast<size_t>(data_size) > size - size_offset - 4) {
    return Status::InvalidArgument("image size " + std::to_string(data_size) +
                                   " does not fit the message");
  }
  return Status::Ok();
}

int64_t ReadInt64(const uint8_t* p) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v = (v << 8) | p[i];
  return static_cast<int64_t>(v);
}

}  // namespace

StatusOr<frame_t> DecodeFrameHead(const void* data, size_t size) {
  const auto* bytes = static_cast<const uint8_t*>(data);
  if (data == nullptr || size < kRobotLengthOffset + 4) {
    return Status::InvalidArgument("too short for a frame head");
  }
  if (ReadInt64(bytes) != frame_t::getHash()) {
    return Status::InvalidArgument("not a placerec.frame_t (fingerprint mismatch)");
  }
  int32_t robot_length = 0;  // LCM strings: length with the terminating NUL, then the bytes
  ReadInt32(bytes, size, kRobotLengthOffset, &robot_length);
  const size_t robot_begin = kRobotLengthOffset + 4;
  if (robot_length < 1 || static_cast<size_t>(robot_length) > size - robot_begin) {
    return Status::InvalidArgument("robot id does not fit the message");
  }
  frame_t frame;
  frame.utime = ReadInt64(bytes + 8);
  frame.sequence = ReadInt64(bytes + 16);
  frame.request_id = ReadInt64(bytes + 24);
  frame.insert = bytes[32] != 0;
  frame.encoding = static_cast<int8_t>(bytes[33]);
  ReadInt32(bytes, size, 34, &frame.width);
  ReadInt32(bytes, size, 38, &frame.height);
  frame.robot.assign(reinterpret_cast<const char*>(bytes + robot_begin),
                     static_cast<size_t>(robot_length) - 1);
  frame.size = 0;
  ClearFrameSignature(&frame);  // the head is never authenticated
  return frame;
}

StatusOr<frame_t> DecodeFrameMessage(const void* data, size_t size) {
  if (data == nullptr || size < 8) {
    return Status::InvalidArgument("message of " + std::to_string(size) +
                                   " bytes is too short for a frame");
  }
  if (size > static_cast<size_t>(INT32_MAX)) {
    return Status::InvalidArgument("message of " + std::to_string(size) + " bytes is too large");
  }
  const auto* bytes = static_cast<const uint8_t*>(data);
  // The fingerprint first, so that other message types get a clear reason.
  int64_t hash = 0;
  if (__int64_t_decode_array(bytes, 0, static_cast<int>(size), &hash, 1) != 8 ||
      hash != frame_t::getHash()) {
    return Status::InvalidArgument("not a placerec.frame_t (fingerprint mismatch)");
  }
  PLACEREC_RETURN_IF_ERROR(CheckFrameLengths(bytes, size));
  frame_t frame;
  int decoded = -1;
  try {
    decoded = frame.decode(bytes, 0, static_cast<int>(size));
  } catch (const std::exception& e) {
    return Status::InvalidArgument(std::string("malformed frame_t: ") + e.what());
  }
  if (decoded < 0) return Status::InvalidArgument("malformed or truncated frame_t");
  if (static_cast<size_t>(decoded) != size) {
    return Status::InvalidArgument("frame_t followed by " + std::to_string(size - decoded) +
                                   " unexpected bytes");
  }
  return frame;
}

StatusOr<ImageEncoding> ImageEncodingFromWire(int8_t encoding) {
  switch (encoding) {
    case frame_t::ENCODING_JPEG:
      return ImageEncoding::kJpeg;
    case frame_t::ENCODING_PNG:
      return ImageEncoding::kPng;
    case frame_t::ENCODING_RAW_BGR8:
      return ImageEncoding::kRawBgr8;
    case frame_t::ENCODING_RAW_GRAY8:
      return ImageEncoding::kRawGray8;
    default:
      break;
  }
  return Status::BadImage("unsupported image encoding " + std::to_string(encoding) +
                          " (supported: 0 jpeg, 1 png, 2 raw-bgr8, 3 raw-gray8)");
}

FrameRequest ToFrameRequest(const frame_t& frame) {
  FrameRequest request;
  request.robot = frame.robot;
  request.sequence = frame.sequence;
  request.utime = frame.utime;
  request.insert = frame.insert;
  return request;
}

int8_t WireStatus(StatusCode code) {
  switch (code) {
    case StatusCode::kOk:
      return result_t::STATUS_OK;
    case StatusCode::kInvalidArgument:
    case StatusCode::kNotFound:
      return result_t::STATUS_BAD_REQUEST;
    case StatusCode::kBadImage:
      return result_t::STATUS_BAD_IMAGE;
    case StatusCode::kIoError:
      return result_t::STATUS_STORAGE_ERROR;
    case StatusCode::kOverloaded:
      return result_t::STATUS_OVERLOADED;
    case StatusCode::kInternal:
      return result_t::STATUS_INTERNAL_ERROR;
  }
  return result_t::STATUS_INTERNAL_ERROR;
}

const char* WireStatusName(int8_t status) {
  switch (status) {
    case result_t::STATUS_OK:
      return "ok";
    case result_t::STATUS_BAD_REQUEST:
      return "bad request";
    case result_t::STATUS_BAD_IMAGE:
      return "bad image";
    case result_t::STATUS_UNKNOWN_ROBOT:
      return "unknown robot";
    case result_t::STATUS_OVERLOADED:
      return "overloaded";
    case result_t::STATUS_UNAUTHORISED:
      return "unauthorised";
    case result_t::STATUS_INTERNAL_ERROR:
      return "internal error";
    case result_t::STATUS_STORAGE_ERROR:
      return "storage error";
    case result_t::STATUS_SHUTTING_DOWN:
      return "shutting down";
    default:
      return "unknown status";
  }
}

namespace {

// A box in processed pixels as x, y, width, height in pixels of the frame as sent.
std::array<int32_t, 4> BoxInFrame(const cv::Rect& box, double image_scale) {
  const double to_frame = image_scale > 0 ? 1.0 / image_scale : 1.0;
  const int32_t x = static_cast<int32_t>(std::lround(box.x * to_frame));
  const int32_t y = static_cast<int32_t>(std::lround(box.y * to_frame));
  return {x, y, static_cast<int32_t>(std::lround(box.br().x * to_frame)) - x,
          static_cast<int32_t>(std::lround(box.br().y * to_frame)) - y};
}

void ClearChanges(result_t* answer) {
  answer->num_changes = 0;
  answer->change_kinds.clear();
  answer->change_boxes.clear();
  answer->change_classes.clear();
  answer->change_confidences.clear();
}

}  // namespace

result_t AnswerTemplate(const frame_t& frame) {
  result_t answer;
  answer.utime = 0;
  answer.robot = frame.robot.substr(0, kMaxEchoedRobotIdLength);
  answer.sequence = frame.sequence;
  answer.request_id = frame.request_id;
  answer.frame_utime = frame.utime;
  answer.insert = frame.insert != 0;  // LCM keeps a boolean's byte as sent
  answer.status = result_t::STATUS_OK;
  answer.loop_closure = false;
  answer.num_matches = 0;
  answer.keypoints = 0;
  answer.objects = 0;
  answer.landmarks = 0;
  answer.stored_descriptors = 0;
  answer.place_id = PlaceId::kInvalidValue;
  answer.map_places = 0;
  answer.map_landmarks = 0;
  answer.map_descriptors = 0;
  answer.change_checked = false;
  answer.change_place_id = PlaceId::kInvalidValue;
  answer.num_changes = 0;
  answer.next_sequence = -1;
  answer.queue_ms = 0;
  answer.server_ms = 0;
  answer.num_timings = 0;
  ClearAnswerSignature(&answer);
  return answer;
}

void FillAnswer(const RecognitionResult& result, result_t* answer) {
  answer->map_places = result.map.places;
  answer->map_landmarks = result.map.landmarks;
  answer->map_descriptors = result.map.descriptors;
  for (const auto& [stage, ms] : result.timings) {
    stage_time_t timing;
    timing.stage = stage;
    timing.ms = ms;
    answer->timings.push_back(std::move(timing));
  }
  answer->num_timings = static_cast<int32_t>(answer->timings.size());
  answer->keypoints = result.keypoints;
  answer->objects = result.objects;
  if (!result.status.ok()) {
    SetError(WireStatus(result.status.code()), result.status.message(), answer);
    return;
  }
  answer->status = result_t::STATUS_OK;
  answer->message.clear();
  answer->loop_closure = result.loop_closure;
  answer->matches.clear();
  for (const PlaceMatch& match : result.matches) {
    match_t m;
    m.utime = match.place.utime;
    m.robot = match.place.robot;
    m.sequence = match.place.sequence;
    m.place_id = match.place.id.value();
    m.score = match.score;
    m.matched_landmarks = match.matched_landmarks;
    m.matched_descriptors = match.matched_descriptors;
    m.inliers = match.inliers;
    for (const auto& [name, count] : match.landmark_classes) {
      m.classes.push_back(name);
      m.class_counts.push_back(count);
    }
    m.num_classes = static_cast<int32_t>(m.classes.size());
    answer->matches.push_back(std::move(m));
  }
  answer->num_matches = static_cast<int32_t>(answer->matches.size());
  answer->landmarks = result.landmarks;
  answer->stored_descriptors = result.stored_descriptors;
  answer->place_id = result.place.value();
  answer->change_checked = result.change.checked;
  answer->change_place_id = result.change.place.id.value();
  ClearChanges(answer);
  for (const SceneChange& change : result.change.changes) {
    const std::array<int32_t, 4> box = BoxInFrame(change.box, result.image_scale);
    // Copies of the constants: a conditional of the two would refer to them (ODR use).
    const int8_t appeared = result_t::CHANGE_APPEARED;
    const int8_t disappeared = result_t::CHANGE_DISAPPEARED;
    answer->change_kinds.push_back(change.kind == SceneChange::Kind::kAppeared ? appeared
                                                                               : disappeared);
    answer->change_boxes.emplace_back(box.begin(), box.end());
    answer->change_classes.push_back(change.object_class);
    answer->change_confidences.push_back(change.confidence);
  }
  answer->num_changes = static_cast<int32_t>(answer->change_kinds.size());
}

std::vector<change_t> AlarmMessages(const RecognitionResult& result, const frame_t& frame,
                                    const cv::Size& frame_size) {
  std::vector<change_t> alarms;
  if (!result.status.ok()) return alarms;
  const std::vector<SceneChange>& changes = result.change.changes;
  for (size_t i = 0; i < changes.size(); ++i) {
    change_t alarm;
    alarm.utime = 0;
    alarm.robot = frame.robot;
    alarm.sequence = frame.sequence;
    alarm.request_id = frame.request_id;
    alarm.frame_utime = frame.utime;
    const Place& place = result.change.place;
    alarm.place_id = place.id.value();
    alarm.place_robot = place.robot;
    alarm.place_sequence = place.sequence;
    alarm.place_utime = place.utime;
    alarm.change_index = static_cast<int32_t>(i);
    alarm.num_frame_changes = static_cast<int32_t>(changes.size());
    const int8_t appeared = change_t::KIND_APPEARED;
    const int8_t disappeared = change_t::KIND_DISAPPEARED;
    alarm.kind = changes[i].kind == SceneChange::Kind::kAppeared ? appeared : disappeared;
    const std::array<int32_t, 4> box = BoxInFrame(changes[i].box, result.image_scale);
    std::copy(box.begin(), box.end(), alarm.box);
    alarm.object_class = changes[i].object_class;
    alarm.confidence = changes[i].confidence;
    alarm.frame_width = frame_size.width;
    alarm.frame_height = frame_size.height;
    alarm.frame_jpeg.assign(result.change.frame_picture.begin(), result.change.frame_picture.end());
    alarm.frame_jpeg_size = static_cast<int32_t>(alarm.frame_jpeg.size());
    alarm.place_jpeg.assign(result.change.place_picture.begin(), result.change.place_picture.end());
    alarm.place_jpeg_size = static_cast<int32_t>(alarm.place_jpeg.size());
    alarms.push_back(std::move(alarm));
  }
  return alarms;
}

void SetError(int8_t status, const std::string& message, result_t* answer) {
  answer->status = status;
  answer->message = message;
  answer->loop_closure = false;
  answer->matches.clear();
  answer->num_matches = 0;
  answer->landmarks = 0;
  answer->stored_descriptors = 0;
  answer->place_id = PlaceId::kInvalidValue;
  answer->change_checked = false;
  answer->change_place_id = PlaceId::kInvalidValue;
  ClearChanges(answer);
}

}  // namespace placerec
