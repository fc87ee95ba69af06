#include "server/authenticator.h"

#include <sys/stat.h>
#include <unistd.h>

#include <fstream>
#include <limits>
#include <string>

#include <gtest/gtest.h>

namespace placerec {
namespace {

constexpr int64_t kStart = 1800000000000000;  // the server's start, microseconds since the epoch
constexpr int64_t kSecond = 1000000;

const char kRobotHex[] = "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f";
const char kPhoneHex[] = "ffeeddccbbaa99887766554433221100ffeeddccbbaa99887766554433221100";
const char kLateHex[] = "0f0e0d0c0b0a09080706050403020100ffeeddccbbaa99887766554433221100";

// Files of this process only: ctest runs the tests of this file in parallel processes, which
// must not read each other's half-written files.
std::string TempPath(const std::string& name) {
  return ::testing::TempDir() + "/" + name + "_" + std::to_string(getpid());
}

std::string WriteKeys(const std::string& text) {
  const std::string path = TempPath("authenticator_keys");
  std::ofstream(path, std::ios::trunc) << text;
  chmod(path.c_str(), 0600);
  return path;
}

SigningKey Key(const std::string& id, const std::string& hex) {
  std::string warning;
  const std::string path = TempPath("authenticator_one_key");
  std::ofstream(path, std::ios::trunc) << id << " both " << hex << "\n";
  return ReadKeysFile(path, &warning)->front();
}

frame_t Frame(bool insert) {
  frame_t frame;
  frame.utime = kStart;
  frame.sequence = 3;
  frame.request_id = 9;
  frame.insert = insert;
  frame.encoding = frame_t::ENCODING_JPEG;
  frame.width = frame.height = 0;
  frame.robot = "robot";
  ClearFrameSignature(&frame);
  frame.data = {1, 2, 3};
  frame.size = 3;
  return frame;
}

frame_t Signed(const SigningKey& key, int64_t counter, int64_t utime, bool insert = true) {
  frame_t frame = Frame(insert);
  SignFrame(key, counter, utime, &frame);
  return frame;
}

class AuthenticatorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    options_.keys_file =
        WriteKeys(std::string("robot both ") + kRobotHex + "\nphone query " + kPhoneHex + "\n");
    StatusOr<Authenticator> auth = Authenticator::Create(options_, kStart);
    ASSERT_TRUE(auth.ok()) << auth.status().ToString();
    auth_ = std::make_unique<Authenticator>(std::move(*auth));
  }
  AuthOptions options_;
  std::unique_ptr<Authenticator> auth_;
  const SigningKey robot_ = Key("robot", kRobotHex);
  const SigningKey phone_ = Key("phone", kPhoneHex);
};

TEST_F(AuthenticatorTest, AcceptsASignedFrameAndNamesItsKey) {
  const Authenticator::Verdict v =
      auth_->Check(Signed(robot_, 1, kStart + kSecond), kStart + 2 * kSecond);
  EXPECT_TRUE(v.ok) << v.message;
  ASSERT_TRUE(v.key.has_value());
  EXPECT_EQ(v.key->id, "robot");
  EXPECT_EQ(v.key->secret, robot_.secret);
}

TEST_F(AuthenticatorTest, RefusesUnsignedUnknownAndBadlySignedFrames) {
  const int64_t now = kStart + kSecond;
  Authenticator::Verdict v = auth_->Check(Frame(true), now);
  EXPECT_FALSE(v.ok);
  EXPECT_FALSE(v.key.has_value());
  EXPECT_NE(v.message.find("--key-file"), std::string::npos) << v.message;
  EXPECT_NE(v.message.find("--auth off"), std::string::npos) << v.message;

  v = auth_->Check(Signed(Key("ghost", kRobotHex), 1, now), now);
  EXPECT_FALSE(v.ok);
  EXPECT_NE(v.message.find("unknown key id 'ghost'"), std::string::npos) << v.message;

  v = auth_->Check(Signed(Key("robot", kPhoneHex), 1, now), now);  // wrong secret
  EXPECT_FALSE(v.ok);
  EXPECT_FALSE(v.key.has_value());
  EXPECT_NE(v.message.find("signature does not match"), std::string::npos) << v.message;

  frame_t tampered = Signed(robot_, 2, now);
  tampered.data[1] ^= 0x40;
  v = auth_->Check(tampered, now);
  EXPECT_FALSE(v.ok);
  EXPECT_NE(v.message.find("signature does not match"), std::string::npos) << v.message;
}

TEST_F(AuthenticatorTest, RefusesReplaysAndFramesOutsideTheWindow) {
  const int64_t now = kStart + 100 * kSecond;
  const frame_t first = Signed(robot_, 10, now);
  EXPECT_TRUE(auth_->Check(first, now).ok);
  Authenticator::Verdict v = auth_->Check(first, now + kSecond);
  EXPECT_FALSE(v.ok);
  EXPECT_TRUE(v.replayed);  // not answered: the original has its answer
  EXPECT_NE(v.message.find("replayed"), std::string::npos) << v.message;
  // Out of order within the window is fine once; again it is a replay.
  EXPECT_TRUE(auth_->Check(Signed(robot_, 12, now), now).ok);
  EXPECT_TRUE(auth_->Check(Signed(robot_, 11, now), now).ok);
  EXPECT_FALSE(auth_->Check(Signed(robot_, 11, now), now).ok);
  // Another frame reusing a counter (e.g. two processes sharing a key, clocks apart) is no copy:
  // refused with a signed answer saying why.
  v = auth_->Check(Signed(robot_, 11, now, /*insert=*/false), now);
  EXPECT_FALSE(v.ok);
  EXPECT_FALSE(v.replayed);
  EXPECT_TRUE(v.key.has_value());
  EXPECT_NE(v.message.find("already used counter"), std::string::npos) << v.message;
  // Another key's counters are its own.
  EXPECT_TRUE(auth_->Check(Signed(phone_, 10, now, false), now).ok);

  v = auth_->Check(Signed(robot_, 20, now - 31 * kSecond), now);
  EXPECT_FALSE(v.ok);
  EXPECT_FALSE(v.replayed);
  EXPECT_TRUE(v.key.has_value());  // the sender is known: its refusal is signed
  EXPECT_NE(v.message.find("window"), std::string::npos) << v.message;
  // The message says which way the sender's clock is off (it said -31 s for a clock ahead).
  EXPECT_NE(v.message.find("signing time is 31 s behind the server's clock"), std::string::npos)
      << v.message;
  v = auth_->Check(Signed(robot_, 21, now + 31 * kSecond), now);
  EXPECT_FALSE(v.ok);
  EXPECT_NE(v.message.find("signing time is 31 s ahead of the server's clock"), std::string::npos)
      << v.message;
  // Times at the ends of the 64-bit range (a signed frame may carry any): refused, no overflow.
  for (const int64_t extreme :
       {std::numeric_limits<int64_t>::min(), std::numeric_limits<int64_t>::max()}) {
    v = auth_->Check(Signed(robot_, 23, extreme), now);
    EXPECT_FALSE(v.ok);
    EXPECT_NE(v.message.find("window"), std::string::npos) << v.message;
  }
  v = auth_->Check(Signed(robot_, 22, kStart - kSecond), kStart + kSecond);
  EXPECT_FALSE(v.ok);
  EXPECT_NE(v.message.find("before the server started"), std::string::npos) << v.message;

  // Counters older than the window are forgotten, and anything up to them is refused.
  const int64_t later = now + 60 * kSecond;
  EXPECT_TRUE(auth_->Check(Signed(robot_, 30, later), later).ok);
  EXPECT_FALSE(auth_->Check(Signed(robot_, 9, later), later).ok);
  EXPECT_FALSE(auth_->Check(Signed(robot_, 12, later), later).ok);
  // A counter never used but below the forgotten ones is not called "already used".
  v = auth_->Check(Signed(robot_, 5, later), later);
  EXPECT_FALSE(v.ok);
  EXPECT_EQ(v.message.find("already used"), std::string::npos) << v.message;
  EXPECT_NE(v.message.find("counter 5 of key"), std::string::npos) << v.message;
  EXPECT_NE(v.message.find("no longer remembers"), std::string::npos) << v.message;
}

TEST_F(AuthenticatorTest, PermissionsDecideInsertAndQuery) {
  const int64_t now = kStart + kSecond;
  Authenticator::Verdict v = auth_->Check(Signed(phone_, 1, now, /*insert=*/true), now);
  EXPECT_FALSE(v.ok);
  EXPECT_NE(v.message.find("may only query"), std::string::npos) << v.message;
  EXPECT_TRUE(auth_->Check(Signed(phone_, 2, now, false), now).ok);

  options_.keys_file = WriteKeys(std::string("logger insert ") + kRobotHex + "\n");
  StatusOr<Authenticator> insert_only = Authenticator::Create(options_, kStart);
  ASSERT_TRUE(insert_only.ok());
  v = insert_only->Check(Signed(Key("logger", kRobotHex), 1, now, false), now);
  EXPECT_FALSE(v.ok);
  EXPECT_NE(v.message.find("may only insert"), std::string::npos) << v.message;
}

TEST_F(AuthenticatorTest, ReloadAddsAndRemovesKeysAndKeepsReplayState) {
  const int64_t now = kStart + kSecond;
  const SigningKey late = Key("late", kLateHex);
  EXPECT_FALSE(auth_->Check(Signed(late, 1, now), now).ok);
  const frame_t sent = Signed(robot_, 1, now);
  EXPECT_TRUE(auth_->Check(sent, now).ok);

  WriteKeys(std::string("robot both ") + kRobotHex + "\nlate both " + kLateHex + "\n");
  ASSERT_TRUE(auth_->Reload().ok());
  EXPECT_TRUE(auth_->Check(Signed(late, 1, now), now).ok);
  EXPECT_FALSE(auth_->Check(sent, now).ok) << "a reload must not reopen replays";

  WriteKeys(std::string("late both ") + kLateHex + "\n");
  ASSERT_TRUE(auth_->Reload().ok());
  const Authenticator::Verdict v = auth_->Check(Signed(robot_, 2, now), now);
  EXPECT_FALSE(v.ok);
  EXPECT_NE(v.message.find("unknown key id 'robot'"), std::string::npos) << v.message;
  // Added back within the window: its frames already accepted stay replays (the state was
  // dropped with the key, so a removal and an undo reopened them).
  WriteKeys(std::string("robot both ") + kRobotHex + "\nlate both " + kLateHex + "\n");
  ASSERT_TRUE(auth_->Reload().ok());
  EXPECT_TRUE(auth_->Check(sent, now).replayed) << "removing and adding back reopened replays";
  EXPECT_TRUE(auth_->Check(Signed(robot_, 3, now), now).ok);
  WriteKeys(std::string("late both ") + kLateHex + "\n");
  ASSERT_TRUE(auth_->Reload().ok());

  WriteKeys("late both nothex\n");
  EXPECT_FALSE(auth_->Reload().ok());
  EXPECT_TRUE(auth_->Check(Signed(late, 2, now), now).ok) << "the old keys stay";
}

TEST(AuthOptionsTest, AuthIsOnByDefaultAndNeedsKeys) {
  AuthOptions options;
  EXPECT_TRUE(options.enabled);
  std::string error;
  EXPECT_TRUE(options.Check(&error)) << error;
  StatusOr<Authenticator> without_keys = Authenticator::Create(options, kStart);
  ASSERT_FALSE(without_keys.ok());
  EXPECT_NE(without_keys.status().message().find("--keys"), std::string::npos);
  EXPECT_NE(without_keys.status().message().find("--auth off"), std::string::npos);
  AuthOptions window;
  window.window_s = 0;
  EXPECT_FALSE(window.Check(&error));
  EXPECT_NE(error.find("--auth-window"), std::string::npos) << error;
  options.enabled = false;
  StatusOr<Authenticator> off = Authenticator::Create(options, kStart);
  ASSERT_TRUE(off.ok());
  EXPECT_TRUE(off->Check(Frame(true), kStart).ok);
}

}  // namespace
}  // namespace placerec
