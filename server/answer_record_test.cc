// Tests of the server's record of recent frames (answer_record.h): a frame in flight, a frame
// answered, a frame forgotten, the bound per robot and on robots.
#include "server/answer_record.h"

#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace placerec {
namespace {

frame_t Frame(const std::string& robot, int64_t request_id, int64_t sequence) {
  frame_t frame{};
  frame.robot = robot;
  frame.request_id = request_id;
  frame.sequence = sequence;
  frame.utime = 1000 + sequence;
  frame.insert = true;
  return frame;
}

result_t Answer(int64_t place_id) {
  result_t answer;
  answer.place_id = place_id;
  return answer;
}

TEST(AnswerRecordTest, InFlightThenAnsweredAndOnlyTheSameFrameMatches) {
  AnswerRecord record;
  result_t answer;
  const frame_t frame = Frame("a", 7, 3);
  EXPECT_EQ(record.Begin(frame, &answer), AnswerRecord::Seen::kNew);
  EXPECT_EQ(record.Begin(frame, &answer), AnswerRecord::Seen::kInFlight);
  record.Finish(frame, Answer(42));
  ASSERT_EQ(record.Begin(frame, &answer), AnswerRecord::Seen::kAnswered);
  EXPECT_EQ(answer.place_id, 42);
  // Another robot, request id, sequence, capture time or insert flag is another frame.
  frame_t other = frame;
  other.robot = "b";
  EXPECT_EQ(record.Begin(other, &answer), AnswerRecord::Seen::kNew);
  other = frame;
  other.request_id = 8;
  EXPECT_EQ(record.Begin(other, &answer), AnswerRecord::Seen::kNew);
  other = frame;
  other.utime += 1;
  EXPECT_EQ(record.Begin(other, &answer), AnswerRecord::Seen::kNew);
  other = frame;
  other.insert = false;
  EXPECT_EQ(record.Begin(other, &answer), AnswerRecord::Seen::kNew);
}

// A sender that reuses robot, request id, sequence and capture time for another image (a phone
// asking every query as sequence 0 with request id 0) gets that image answered: it got the first
// image's answer again. A resend signed again (new counter, signing time
// and signature, the same image) is still the same frame; another signing key is another frame.
TEST(AnswerRecordTest, AnotherImageOrKeyIsAnotherFrameAndAResignedCopyIsTheSame) {
  AnswerRecord record;
  result_t answer;
  frame_t frame = Frame("phone", 0, 0);
  frame.insert = false;
  frame.key_id = "phone";
  frame.data = {1, 2, 3, 4};
  frame.size = 4;
  EXPECT_EQ(record.Begin(frame, &answer), AnswerRecord::Seen::kNew);
  record.Finish(frame, Answer(42));
  frame_t resigned = frame;
  resigned.auth_counter += 1;
  resigned.auth_utime += 1000;
  resigned.signature[0] ^= 1;
  EXPECT_EQ(record.Begin(resigned, &answer), AnswerRecord::Seen::kAnswered);
  frame_t other = frame;
  other.data = {1, 2, 3, 5};
  EXPECT_EQ(record.Begin(other, &answer), AnswerRecord::Seen::kNew);
  other = frame;
  other.key_id = "robots";
  EXPECT_EQ(record.Begin(other, &answer), AnswerRecord::Seen::kNew);
  other = frame;
  other.encoding = 1;
  EXPECT_EQ(record.Begin(other, &answer), AnswerRecord::Seen::kNew);
}

// LCM decodes a boolean as the byte sent: an insert flag of 2 is an insert like 1, and its copy
// is recognised (it never was: each copy was processed again, and its entry stayed in flight for
// ever, the robot's list growing without bound).
TEST(AnswerRecordTest, AnInsertFlagOtherThanOneIsTheSameFrame) {
  AnswerRecord record;
  result_t answer;
  frame_t frame = Frame("a", 7, 3);
  frame.insert = 2;
  EXPECT_EQ(record.Begin(frame, &answer), AnswerRecord::Seen::kNew);
  EXPECT_EQ(record.Begin(frame, &answer), AnswerRecord::Seen::kInFlight);
  record.Finish(frame, Answer(42));
  ASSERT_EQ(record.Begin(frame, &answer), AnswerRecord::Seen::kAnswered);
  EXPECT_EQ(answer.place_id, 42);
  frame.insert = 1;
  EXPECT_EQ(record.Begin(frame, &answer), AnswerRecord::Seen::kAnswered);
}

TEST(AnswerRecordTest, AFrameNotProcessedIsForgotten) {
  AnswerRecord record;
  result_t answer;
  const frame_t frame = Frame("a", 1, 1);
  EXPECT_EQ(record.Begin(frame, &answer), AnswerRecord::Seen::kNew);
  record.Forget(frame);
  EXPECT_EQ(record.Begin(frame, &answer), AnswerRecord::Seen::kNew);
}

// A copy that comes on another of the server's networks while the frame is in flight (a device
// on the robot LAN and the TCP hub at once, or one that moved) was dropped, and the answer went
// only to the original's network. Now the answer (or the refusal) is owed there too, once.
TEST(AnswerRecordTest, CopiesOnOtherNetworksAreOwedTheAnswer) {
  AnswerRecord record;
  result_t answer;
  const frame_t frame = Frame("a", 7, 3);
  EXPECT_EQ(record.Begin(frame, &answer, 0), AnswerRecord::Seen::kNew);
  EXPECT_EQ(record.Begin(frame, &answer, 0), AnswerRecord::Seen::kInFlight);
  EXPECT_EQ(record.Begin(frame, &answer, 2), AnswerRecord::Seen::kInFlight);
  EXPECT_EQ(record.Begin(frame, &answer, 2), AnswerRecord::Seen::kInFlight);
  EXPECT_EQ(record.Begin(frame, &answer, 1), AnswerRecord::Seen::kInFlight);
  EXPECT_EQ(record.Finish(frame, Answer(42)), (std::vector<size_t>{2, 1}));
  // Answered: a later copy gets the answer again wherever it comes from, and owes nothing.
  ASSERT_EQ(record.Begin(frame, &answer, 1), AnswerRecord::Seen::kAnswered);
  EXPECT_EQ(answer.place_id, 42);

  const frame_t refused = Frame("a", 8, 4);
  EXPECT_EQ(record.Begin(refused, &answer, 1), AnswerRecord::Seen::kNew);
  EXPECT_EQ(record.Begin(refused, &answer, 0), AnswerRecord::Seen::kInFlight);
  EXPECT_EQ(record.Forget(refused), (std::vector<size_t>{0}));
  EXPECT_TRUE(record.Forget(refused).empty());
}

// Byte-identical copies (the replay guard's "replayed") are never processed; one that came on
// another network is owed the answer there, once.
TEST(AnswerRecordTest, AnIdenticalCopyOnAnotherNetworkIsOwedTheAnswerOnce) {
  AnswerRecord record;
  result_t answer;
  const frame_t frame = Frame("a", 7, 3);
  EXPECT_EQ(record.CopyOnNetwork(frame, 1, &answer), AnswerRecord::Seen::kNew);  // unknown
  EXPECT_EQ(record.Begin(frame, &answer, 0), AnswerRecord::Seen::kNew);
  EXPECT_EQ(record.CopyOnNetwork(frame, 0, &answer), AnswerRecord::Seen::kNew);  // its own
  EXPECT_EQ(record.CopyOnNetwork(frame, 1, &answer), AnswerRecord::Seen::kInFlight);
  EXPECT_EQ(record.CopyOnNetwork(frame, 1, &answer), AnswerRecord::Seen::kNew);  // noted once
  EXPECT_EQ(record.Finish(frame, Answer(42)), (std::vector<size_t>{1}));
  EXPECT_EQ(record.CopyOnNetwork(frame, 1, &answer), AnswerRecord::Seen::kNew);  // served
  answer = result_t();
  ASSERT_EQ(record.CopyOnNetwork(frame, 2, &answer), AnswerRecord::Seen::kAnswered);
  EXPECT_EQ(answer.place_id, 42);
  EXPECT_EQ(record.CopyOnNetwork(frame, 2, &answer), AnswerRecord::Seen::kNew);
}

TEST(AnswerRecordTest, KeepsTheLastFramesPerRobotAndFramesInFlight) {
  AnswerRecord record(/*per_robot=*/3, /*max_robots=*/2);
  result_t answer;
  const frame_t in_flight = Frame("a", 0, 0);
  EXPECT_EQ(record.Begin(in_flight, &answer), AnswerRecord::Seen::kNew);
  for (int i = 1; i <= 5; ++i) {
    const frame_t frame = Frame("a", i, i);
    EXPECT_EQ(record.Begin(frame, &answer), AnswerRecord::Seen::kNew);
    record.Finish(frame, Answer(i));
  }
  EXPECT_EQ(record.Begin(in_flight, &answer), AnswerRecord::Seen::kInFlight);
  EXPECT_EQ(record.Begin(Frame("a", 5, 5), &answer), AnswerRecord::Seen::kAnswered);
  EXPECT_EQ(record.Begin(Frame("a", 1, 1), &answer), AnswerRecord::Seen::kNew);  // dropped
  // Two robots at most are recorded: a third's frames are new every time.
  EXPECT_EQ(record.Begin(Frame("b", 1, 1), &answer), AnswerRecord::Seen::kNew);
  EXPECT_EQ(record.Begin(Frame("c", 1, 1), &answer), AnswerRecord::Seen::kNew);
  EXPECT_EQ(record.Begin(Frame("c", 1, 1), &answer), AnswerRecord::Seen::kNew);
}

}  // namespace
}  // namespace placerec
