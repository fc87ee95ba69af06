#include "proto/auth/signing.h"

#include <sys/stat.h>
#include <unistd.h>

#include <cstring>
#include <exception>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace placerec {
namespace {

// In files of this process only: ctest runs this file's tests in parallel processes.
std::string WriteFile(const std::string& name, const std::string& text, mode_t mode) {
  const std::string path = ::testing::TempDir() + "/" + name + "_" + std::to_string(getpid());
  std::ofstream(path) << text;
  chmod(path.c_str(), mode);
  return path;
}

const char kHexA[] = "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f";
const char kHexB[] = "ffeeddccbbaa99887766554433221100ffeeddccbbaa99887766554433221100";

SigningKey KeyOf(const std::string& id, const std::string& hex) {
  std::string warning;
  const std::string path = WriteFile("one_key_" + id, id + " both " + hex + "\n", 0600);
  StatusOr<std::vector<SigningKey>> keys = ReadKeysFile(path, &warning);
  EXPECT_TRUE(keys.ok()) << keys.status().ToString();
  return keys.ok() && !keys->empty() ? keys->front() : SigningKey();
}

frame_t TestFrame() {
  frame_t frame;
  frame.utime = 1700000000000000;
  frame.sequence = 7;
  frame.request_id = 42;
  frame.insert = true;
  frame.encoding = frame_t::ENCODING_JPEG;
  frame.width = 0;
  frame.height = 0;
  frame.robot = "left";
  ClearFrameSignature(&frame);
  frame.data = {0xff, 0xd8, 0xff, 1, 2, 3, 4, 5};
  frame.size = static_cast<int32_t>(frame.data.size());
  return frame;
}

// RFC 4231 test case 2: the HMAC is OpenSSL's HMAC-SHA256, not something of our own.
TEST(SigningTest, HmacSha256MatchesRfc4231) {
  const std::string data = "what do ya want for nothing?";
  const Signature mac = HmacSha256("Jefe", data.data(), data.size());
  static const char kExpected[] =
      "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843";
  std::string hex;
  for (uint8_t b : mac) {
    char two[3];
    std::snprintf(two, sizeof(two), "%02x", b);
    hex += two;
  }
  EXPECT_EQ(hex, kExpected);
}

TEST(SigningTest, ReadsKeysFilesAndSaysWhatIsWrong) {
  std::string warning;
  const std::string good =
      WriteFile("keys_good",
                "# placerec keys\n\nleft both " + std::string(kHexA) + "\nphone query " + kHexB +
                    "  # a handheld\n" + "logger insert " + kHexA + "\n",
                0600);
  StatusOr<std::vector<SigningKey>> keys = ReadKeysFile(good, &warning);
  ASSERT_TRUE(keys.ok()) << keys.status().ToString();
  EXPECT_TRUE(warning.empty()) << warning;
  ASSERT_EQ(keys->size(), 3u);
  EXPECT_EQ((*keys)[0].id, "left");
  EXPECT_TRUE((*keys)[0].may_insert && (*keys)[0].may_query);
  EXPECT_EQ((*keys)[1].id, "phone");
  EXPECT_TRUE(!(*keys)[1].may_insert && (*keys)[1].may_query);
  EXPECT_TRUE((*keys)[2].may_insert && !(*keys)[2].may_query);
  ASSERT_EQ((*keys)[0].secret.size(), kKeyBytes);
  EXPECT_EQ(static_cast<uint8_t>((*keys)[0].secret[31]), 0x1f);
  EXPECT_EQ(FindKey(*keys, "phone"), &(*keys)[1]);
  EXPECT_EQ(FindKey(*keys, ""), &(*keys)[0]);
  EXPECT_EQ(FindKey(*keys, "nobody"), nullptr);

  const std::string open = WriteFile("keys_open", "left both " + std::string(kHexA) + "\n", 0644);
  ASSERT_TRUE(ReadKeysFile(open, &warning).ok());
  EXPECT_NE(warning.find("chmod 600"), std::string::npos) << warning;

  struct Bad {
    std::string text;
    std::string says;
  };
  const std::vector<Bad> bad = {
      {"left both 0011\n", "64 hex digits"},
      {"left all " + std::string(kHexA) + "\n", "insert, query or both"},
      {"left both " + std::string(kHexA) + "\nleft query " + kHexB + "\n", "twice"},
      {"le/ft both " + std::string(kHexA) + "\n", "key id"},
      {"left both\n", "ID PERMISSION KEY"},
  };
  for (const Bad& b : bad) {
    const std::string path = WriteFile("keys_bad", b.text, 0600);
    StatusOr<std::vector<SigningKey>> read = ReadKeysFile(path, &warning);
    ASSERT_FALSE(read.ok()) << b.text;
    EXPECT_NE(read.status().message().find(b.says), std::string::npos) << read.status().message();
    EXPECT_NE(read.status().message().find("line "), std::string::npos);
  }
  EXPECT_FALSE(ReadKeysFile(::testing::TempDir() + "/no_such_keys", &warning).ok());
}

TEST(SigningTest, AFrameSignatureCoversEveryByte) {
  const SigningKey key = KeyOf("left", kHexA);
  const SigningKey other = KeyOf("left", kHexB);
  frame_t frame = TestFrame();
  EXPECT_TRUE(FrameIsUnsigned(frame));
  SignFrame(key, 5, 1700000000000001, &frame);
  EXPECT_FALSE(FrameIsUnsigned(frame));
  EXPECT_EQ(frame.key_id, "left");
  EXPECT_TRUE(FrameSignatureValid(frame, key.secret));
  EXPECT_FALSE(FrameSignatureValid(frame, other.secret));

  // The recipe of proto/README.md, as a client written from the .lcm files would follow it.
  frame_t by_hand = frame;
  std::memset(by_hand.signature, 0, kSignatureBytes);
  const std::vector<uint8_t> bytes = EncodeFrame(by_hand);
  const Signature mac = HmacSha256(key.secret, bytes.data(), bytes.size());
  EXPECT_EQ(std::memcmp(mac.data(), frame.signature, kSignatureBytes), 0);

  // Every byte of the encoded message counts: change each one in turn.
  const std::vector<uint8_t> signed_bytes = EncodeFrame(frame);
  EXPECT_EQ(FrameSignatureOffset(frame) + kSignatureBytes + 4 + frame.data.size(),
            signed_bytes.size());
  EXPECT_TRUE(FrameSignatureValid(frame, key.secret, signed_bytes.data(), signed_bytes.size()));
  int decoded_and_valid = 0;
  for (size_t i = 0; i < signed_bytes.size(); ++i) {
    std::vector<uint8_t> tampered = signed_bytes;
    tampered[i] ^= 0x01;
    frame_t copy;
    try {  // a changed length may make the generated decoder throw
      if (copy.decode(tampered.data(), 0, static_cast<int>(tampered.size())) < 0) continue;
    } catch (const std::exception&) {
      continue;
    }
    if (FrameSignatureValid(copy, key.secret, tampered.data(), tampered.size())) {
      ++decoded_and_valid;
    }
  }
  EXPECT_EQ(decoded_and_valid, 0);
}

TEST(SigningTest, AnAnswerSignatureNamesItsKey) {
  const SigningKey key = KeyOf("left", kHexA);
  result_t answer{};
  answer.utime = 1;
  answer.robot = "left";
  answer.sequence = 7;
  answer.request_id = 42;
  answer.frame_utime = 2;
  answer.insert = true;
  answer.status = result_t::STATUS_OK;
  answer.loop_closure = false;
  answer.num_matches = 0;
  answer.keypoints = answer.objects = answer.landmarks = answer.stored_descriptors = 0;
  answer.place_id = -1;
  answer.map_places = answer.map_landmarks = answer.map_descriptors = 0;
  answer.queue_ms = answer.server_ms = 0;
  answer.num_timings = 0;
  answer.change_checked = false;
  answer.change_place_id = -1;
  answer.num_changes = 0;
  ClearAnswerSignature(&answer);
  EXPECT_FALSE(AnswerSignatureValid(answer, key));  // unsigned
  SignAnswer(key, &answer);
  EXPECT_TRUE(AnswerSignatureValid(answer, key));
  result_t forged = answer;
  forged.loop_closure = true;
  EXPECT_FALSE(AnswerSignatureValid(forged, key));
  SigningKey renamed = key;
  renamed.id = "right";
  EXPECT_FALSE(AnswerSignatureValid(answer, renamed));
  EXPECT_FALSE(AnswerSignatureValid(answer, KeyOf("left", kHexB)));
}

}  // namespace
}  // namespace placerec
