#include "server/protocol.h"

#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "proto/auth/signing.h"
#include "proto/channels.h"

namespace placerec {
namespace {

frame_t MakeFrame(const std::string& robot, int bytes) {
  frame_t frame;
  frame.utime = 1400000000000000;
  frame.sequence = 7;
  frame.request_id = 99;
  frame.insert = true;
  frame.encoding = frame_t::ENCODING_RAW_GRAY8;
  frame.width = 4;
  frame.height = bytes / 4;
  frame.robot = robot;
  ClearFrameSignature(&frame);
  frame.size = bytes;
  frame.data.assign(bytes, 0x5a);
  return frame;
}

std::vector<uint8_t> Encode(const frame_t& frame) {
  std::vector<uint8_t> bytes(frame.getEncodedSize());
  EXPECT_EQ(frame.encode(bytes.data(), 0, static_cast<int>(bytes.size())),
            static_cast<int>(bytes.size()));
  return bytes;
}

// Offset of frame_t's key id length for a robot id of `robot_length` bytes.
size_t KeyIdOffset(size_t robot_length) {
  return 8 + 8 + 8 + 8 + 1 + 1 + 4 + 4 + 4 + robot_length + 1;
}

// Offset of frame_t's `size` field for a robot id of `robot_length` bytes and a key id of
// `key_id_length` bytes (after them: auth_counter, auth_utime, signature[32]).
size_t SizeOffset(size_t robot_length, size_t key_id_length = 0) {
  return KeyIdOffset(robot_length) + 4 + key_id_length + 1 + 8 + 8 + 32;
}

void PutInt32(std::vector<uint8_t>* bytes, size_t offset, int32_t value) {
  const uint32_t v = static_cast<uint32_t>(value);
  (*bytes)[offset] = v >> 24;
  (*bytes)[offset + 1] = (v >> 16) & 0xff;
  (*bytes)[offset + 2] = (v >> 8) & 0xff;
  (*bytes)[offset + 3] = v & 0xff;
}

TEST(ProtocolTest, DecodesAnEncodedFrame) {
  const frame_t sent = MakeFrame("left", 64);
  const std::vector<uint8_t> bytes = Encode(sent);
  StatusOr<frame_t> got = DecodeFrameMessage(bytes.data(), bytes.size());
  ASSERT_TRUE(got.ok()) << got.status().ToString();
  EXPECT_EQ(got->robot, "left");
  EXPECT_EQ(got->sequence, 7);
  EXPECT_EQ(got->request_id, 99);
  EXPECT_EQ(got->utime, 1400000000000000);
  EXPECT_TRUE(got->insert);
  EXPECT_EQ(got->size, 64);
  EXPECT_EQ(got->data, sent.data);
  const FrameRequest request = ToFrameRequest(*got);
  EXPECT_EQ(request.robot, "left");
  EXPECT_EQ(request.sequence, 7);
  EXPECT_TRUE(request.insert);
}

TEST(ProtocolTest, RejectsWhatIsNotAFrame) {
  const std::vector<uint8_t> bytes = Encode(MakeFrame("left", 64));
  EXPECT_FALSE(DecodeFrameMessage(bytes.data(), 3).ok());
  EXPECT_FALSE(DecodeFrameMessage(nullptr, 0).ok());
  std::vector<uint8_t> other = bytes;
  other[0] ^= 1;
  const StatusOr<frame_t> wrong = DecodeFrameMessage(other.data(), other.size());
  ASSERT_FALSE(wrong.ok());
  EXPECT_NE(wrong.status().message().find("fingerprint"), std::string::npos);
  // Every truncation is an error, none throws.
  for (size_t n = 0; n < bytes.size(); ++n) {
    EXPECT_FALSE(DecodeFrameMessage(bytes.data(), n).ok()) << n;
  }
  std::vector<uint8_t> longer = bytes;
  longer.push_back(0);
  const StatusOr<frame_t> trailing = DecodeFrameMessage(longer.data(), longer.size());
  ASSERT_FALSE(trailing.ok());
  EXPECT_NE(trailing.status().message().find("1 unexpected bytes"), std::string::npos);
}

// A frame cut short after its robot id, or with a forged image size, still tells who sent it.
TEST(ProtocolTest, HeadOfAMalformedFrame) {
  frame_t frame = MakeFrame("left", 64);
  frame.request_id = 77;
  frame.sequence = 9;
  const std::vector<uint8_t> bytes = Encode(frame);
  const size_t robot_end = 8 + 8 + 8 + 8 + 1 + 1 + 4 + 4 + 4 + 5;
  for (const size_t n : {robot_end, robot_end + 4, bytes.size() - 1}) {
    ASSERT_FALSE(DecodeFrameMessage(bytes.data(), n).ok()) << n;
    const StatusOr<frame_t> head = DecodeFrameHead(bytes.data(), n);
    ASSERT_TRUE(head.ok()) << n << ": " << head.status().ToString();
    EXPECT_EQ(head->robot, "left");
    EXPECT_EQ(head->request_id, 77);
    EXPECT_EQ(head->sequence, 9);
    EXPECT_EQ(head->insert, frame.insert);
    EXPECT_TRUE(head->data.empty());
  }
  // Cut inside the robot id, or not a frame_t: nothing to answer.
  EXPECT_FALSE(DecodeFrameHead(bytes.data(), robot_end - 2).ok());
  std::vector<uint8_t> other = bytes;
  other[0] ^= 1;
  EXPECT_FALSE(DecodeFrameHead(other.data(), other.size()).ok());
  EXPECT_FALSE(DecodeFrameHead(nullptr, 0).ok());
}

TEST(ProtocolTest, ForgedLengthsNeitherAllocateNorThrow) {
  const std::vector<uint8_t> bytes = Encode(MakeFrame("left", 64));
  const size_t robot_length_offset = 8 + 8 + 8 + 8 + 1 + 1 + 4 + 4;
  for (int32_t forged : {INT32_MIN, -1, 0, 1000, INT32_MAX}) {
    std::vector<uint8_t> b = bytes;
    PutInt32(&b, robot_length_offset, forged);
    EXPECT_FALSE(DecodeFrameMessage(b.data(), b.size()).ok()) << forged;
  }
  for (int32_t forged : {INT32_MIN, -1, 65, 1 << 30, INT32_MAX}) {
    std::vector<uint8_t> b = bytes;
    PutInt32(&b, SizeOffset(4), forged);
    const StatusOr<frame_t> got = DecodeFrameMessage(b.data(), b.size());
    ASSERT_FALSE(got.ok()) << forged;
    EXPECT_NE(got.status().message().find("image size"), std::string::npos)
        << got.status().message();
  }
  // Protocol 4's key id is a string too: its length is checked before decoding.
  for (int32_t forged : {INT32_MIN, -1, 0, 1000, INT32_MAX}) {
    std::vector<uint8_t> b = bytes;
    PutInt32(&b, KeyIdOffset(4), forged);
    const StatusOr<frame_t> got = DecodeFrameMessage(b.data(), b.size());
    ASSERT_FALSE(got.ok()) << forged;
    EXPECT_NE(got.status().message().find("key id length"), std::string::npos)
        << got.status().message();
  }
  // A signed frame's size is found after its key id.
  frame_t signed_frame = MakeFrame("left", 64);
  signed_frame.key_id = "robots";
  std::vector<uint8_t> b = Encode(signed_frame);
  PutInt32(&b, SizeOffset(4, 6), 1 << 30);
  const StatusOr<frame_t> got = DecodeFrameMessage(b.data(), b.size());
  ASSERT_FALSE(got.ok());
  EXPECT_NE(got.status().message().find("image size"), std::string::npos);
}

TEST(ProtocolTest, RandomMutationsNeverCrash) {
  const std::vector<uint8_t> bytes = Encode(MakeFrame("robot-7", 300));
  std::mt19937 random(1234);
  int accepted = 0;
  for (int i = 0; i < 20000; ++i) {
    std::vector<uint8_t> b = bytes;
    const int flips = 1 + static_cast<int>(random() % 4);
    for (int f = 0; f < flips; ++f) b[random() % b.size()] = static_cast<uint8_t>(random());
    if (random() % 4 == 0) b.resize(random() % b.size());
    if (DecodeFrameMessage(b.data(), b.size()).ok()) ++accepted;
  }
  // Flips in the payload still decode; the point is that nothing crashed.
  EXPECT_GT(accepted, 0);
  for (int i = 0; i < 2000; ++i) {
    std::vector<uint8_t> b(random() % 2000);
    for (uint8_t& x : b) x = static_cast<uint8_t>(random());
    EXPECT_FALSE(DecodeFrameMessage(b.data(), b.size()).ok());
  }
}

TEST(ProtocolTest, Encodings) {
  EXPECT_EQ(*ImageEncodingFromWire(frame_t::ENCODING_JPEG), ImageEncoding::kJpeg);
  EXPECT_EQ(*ImageEncodingFromWire(frame_t::ENCODING_PNG), ImageEncoding::kPng);
  EXPECT_EQ(*ImageEncodingFromWire(frame_t::ENCODING_RAW_BGR8), ImageEncoding::kRawBgr8);
  EXPECT_EQ(*ImageEncodingFromWire(frame_t::ENCODING_RAW_GRAY8), ImageEncoding::kRawGray8);
  const StatusOr<ImageEncoding> bad = ImageEncodingFromWire(9);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), StatusCode::kBadImage);
  EXPECT_NE(bad.status().message().find("unsupported image encoding 9"), std::string::npos);
}

TEST(ProtocolTest, RobotIdsThatNameAChannel) {
  std::string why;
  EXPECT_TRUE(IsValidWireRobotId("left", &why));
  EXPECT_TRUE(IsValidWireRobotId(std::string(kMaxWireRobotIdLength, 'r'), &why));
  EXPECT_FALSE(IsValidWireRobotId(std::string(kMaxWireRobotIdLength + 1, 'r'), &why));
  EXPECT_NE(why.find("the limit is 47"), std::string::npos) << why;
  EXPECT_FALSE(IsValidWireRobotId("", &why));
  EXPECT_FALSE(IsValidWireRobotId("a\nb", &why));
  EXPECT_EQ(ResultChannel("left"), "PLACEREC_RESULT_left");
  EXPECT_EQ(ResultChannel(std::string(100, 'r')), "PLACEREC_RESULT");
  // Bytes that are not valid UTF-8, spaces and other punctuation cannot name a channel every
  // LCM binding subscribes to (issue 23: "r\xff\xfe" was processed and its answer was lost).
  for (const std::string& bad :
       {std::string("r\xff\xfe"), std::string("r\xc3\xa9"), std::string("two words"),
        std::string("a*b"), std::string("a/b")}) {
    EXPECT_FALSE(IsValidWireRobotId(bad, &why)) << bad;
    EXPECT_NE(why.find("not allowed"), std::string::npos) << why;
    EXPECT_EQ(ResultChannel(bad), "PLACEREC_RESULT");
  }
  EXPECT_TRUE(IsValidWireRobotId("robot-7.left_cam", &why)) << why;
  EXPECT_LE(ResultChannel(std::string(kMaxWireRobotIdLength, 'r')).size(), kMaxLcmChannelLength);
}

TEST(ProtocolTest, AnswersCarryTheResult) {
  const frame_t frame = MakeFrame("right", 16);
  RecognitionResult result;
  result.loop_closure = true;
  PlaceMatch match;
  match.place.id = PlaceId(3);
  match.place.robot = "left";
  match.place.sequence = 30;
  match.place.utime = 5;
  match.score = 57;
  match.matched_landmarks = 4;
  match.matched_descriptors = 80;
  match.inliers = 57;
  match.landmark_classes = {{"building", 3}, {"sign", 1}};
  result.matches.push_back(match);
  result.keypoints = 1000;
  result.objects = 12;
  result.landmarks = 3;
  result.stored_descriptors = 40;
  result.place = PlaceId(9);
  result.map.places = 9;
  result.map.landmarks = 30;
  result.map.descriptors = 400;
  result.timings = {{"sift", 40.0}, {"insert", 2.0}};
  result_t answer = AnswerTemplate(frame);
  FillAnswer(result, &answer);
  EXPECT_EQ(answer.robot, "right");
  EXPECT_EQ(answer.sequence, 7);
  EXPECT_EQ(answer.request_id, 99);
  EXPECT_EQ(int{answer.status}, int{result_t::STATUS_OK});
  EXPECT_TRUE(answer.loop_closure);
  ASSERT_EQ(answer.num_matches, 1);
  EXPECT_EQ(answer.matches[0].robot, "left");
  EXPECT_EQ(answer.matches[0].sequence, 30);
  EXPECT_EQ(answer.matches[0].place_id, 3);
  EXPECT_EQ(answer.matches[0].score, 57.0);
  EXPECT_EQ(answer.matches[0].matched_landmarks, 4);
  ASSERT_EQ(answer.matches[0].num_classes, 2);
  EXPECT_EQ(answer.matches[0].classes, (std::vector<std::string>{"building", "sign"}));
  EXPECT_EQ(answer.matches[0].class_counts, (std::vector<int32_t>{3, 1}));
  EXPECT_EQ(answer.place_id, 9);
  EXPECT_EQ(answer.map_landmarks, 30);
  EXPECT_EQ(answer.num_timings, 2);
  EXPECT_EQ(answer.next_sequence, -1);  // the frame processor sets it from the sequence rule
  // It encodes (counts agree with the arrays).
  std::vector<uint8_t> bytes(answer.getEncodedSize());
  EXPECT_GT(answer.encode(bytes.data(), 0, static_cast<int>(bytes.size())), 0);

  result.status = Status::IoError("disk full");
  result_t failed = AnswerTemplate(frame);
  FillAnswer(result, &failed);
  EXPECT_EQ(int{failed.status}, int{result_t::STATUS_STORAGE_ERROR});
  EXPECT_EQ(failed.message, "disk full");
  EXPECT_FALSE(failed.loop_closure);
  EXPECT_EQ(failed.num_matches, 0);
  EXPECT_EQ(failed.place_id, -1);
  EXPECT_EQ(failed.landmarks, 0);
  EXPECT_STREQ(WireStatusName(failed.status), "storage error");
}

TEST(ProtocolTest, ScenesChangesGoIntoTheAnswerAndAlarmsUnderItsSignature) {
  const frame_t frame = MakeFrame("right", 16);
  RecognitionResult result;
  result.loop_closure = true;
  result.image_scale = 0.5;  // the frame was processed at half its size
  result.change.checked = true;
  result.change.place.id = PlaceId(3);
  result.change.place.robot = "left";
  result.change.place.sequence = 30;
  result.change.place.utime = 5;
  SceneChange appeared;
  appeared.box = cv::Rect(10, 20, 30, 40);
  appeared.object_class = "car";
  appeared.confidence = 0.75f;
  SceneChange gone;
  gone.kind = SceneChange::Kind::kDisappeared;
  gone.box = cv::Rect(100, 0, 8, 8);
  gone.confidence = 0.5f;
  result.change.changes = {appeared, gone};
  result.change.frame_picture = {1, 2, 3};
  result.change.place_picture = {4, 5};
  result_t answer = AnswerTemplate(frame);
  FillAnswer(result, &answer);
  EXPECT_TRUE(answer.change_checked);
  EXPECT_EQ(answer.change_place_id, 3);
  ASSERT_EQ(answer.num_changes, 2);
  EXPECT_EQ(answer.change_kinds, (std::vector<int8_t>{0, 1}));
  EXPECT_EQ(answer.change_boxes[0], (std::vector<int32_t>{20, 40, 60, 80}));  // frame pixels
  EXPECT_EQ(answer.change_classes, (std::vector<std::string>{"car", ""}));
  EXPECT_EQ(answer.change_confidences, (std::vector<float>{0.75f, 0.5f}));

  // Signed over the whole message: changing a change breaks the signature.
  SigningKey key;
  key.id = "k";
  key.secret = std::string(32, 'a');
  SignAnswer(key, &answer);
  std::vector<uint8_t> bytes = EncodeAnswer(answer);
  EXPECT_TRUE(AnswerSignatureValid(answer, key, bytes.data(), bytes.size()));
  result_t tampered = answer;
  tampered.change_confidences[1] = 0.0f;
  EXPECT_FALSE(AnswerSignatureValid(tampered, key));

  // One alarm per change, with the stored visit and both pictures.
  const std::vector<change_t> alarms = AlarmMessages(result, frame, cv::Size(1280, 960));
  ASSERT_EQ(alarms.size(), 2u);
  EXPECT_EQ(alarms[0].robot, "right");
  EXPECT_EQ(alarms[0].sequence, 7);
  EXPECT_EQ(alarms[0].place_id, 3);
  EXPECT_EQ(alarms[0].place_robot, "left");
  EXPECT_EQ(alarms[0].place_sequence, 30);
  EXPECT_EQ(alarms[0].place_utime, 5);
  EXPECT_EQ(int{alarms[0].kind}, int{change_t::KIND_APPEARED});
  EXPECT_EQ(int{alarms[1].kind}, int{change_t::KIND_DISAPPEARED});
  EXPECT_EQ(alarms[0].box[2], 60);
  EXPECT_EQ(alarms[0].object_class, "car");
  EXPECT_EQ(alarms[1].change_index, 1);
  EXPECT_EQ(alarms[1].num_frame_changes, 2);
  EXPECT_EQ(alarms[0].frame_width, 1280);
  EXPECT_EQ(alarms[0].frame_jpeg_size, 3);
  EXPECT_EQ(alarms[0].place_jpeg, (std::vector<uint8_t>{4, 5}));
  std::vector<uint8_t> alarm_bytes(alarms[0].getEncodedSize());
  EXPECT_GT(alarms[0].encode(alarm_bytes.data(), 0, static_cast<int>(alarm_bytes.size())), 0);

  // An error answer carries no changes and no alarms.
  result.status = Status::IoError("disk full");
  result_t failed = AnswerTemplate(frame);
  FillAnswer(result, &failed);
  EXPECT_EQ(failed.num_changes, 0);
  EXPECT_TRUE(failed.change_kinds.empty());
  EXPECT_TRUE(AlarmMessages(result, frame, cv::Size(1280, 960)).empty());
}

TEST(ProtocolTest, LongRobotIdsAreCutInTheEcho) {
  const frame_t frame = MakeFrame(std::string(5000, 'x'), 16);
  EXPECT_EQ(AnswerTemplate(frame).robot.size(), kMaxEchoedRobotIdLength);
}

}  // namespace
}  // namespace placerec
