// The gateway's tokens file and rate limit (gateway/access.h).
#include "gateway/access.h"

#include <gtest/gtest.h>

namespace placerec {
namespace {

bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(TokenTableTest, KnownTokensNameTheirDeviceUntilTheyExpire) {
  StatusOr<TokenTable> table = TokenTable::Parse(
      "# field devices\n"
      "\n"
      "0123456789abcdef0123 phone-anna\n"
      "fedcba9876543210fedc handheld.2 expires=2026-01-01T00:00:00Z\n");
  ASSERT_TRUE(table.ok()) << table.status().ToString();
  EXPECT_EQ(table->size(), 2u);
  const int64_t new_year_2026 = 1767225600;
  StatusOr<DeviceToken> anna = table->Authenticate("0123456789abcdef0123", new_year_2026 + 1);
  ASSERT_TRUE(anna.ok());
  EXPECT_EQ(anna->device, "phone-anna");
  EXPECT_EQ(anna->key_id, "");
  StatusOr<DeviceToken> before = table->Authenticate("fedcba9876543210fedc", new_year_2026);
  ASSERT_TRUE(before.ok());
  EXPECT_EQ(before->device, "handheld.2");
  StatusOr<DeviceToken> after = table->Authenticate("fedcba9876543210fedc", new_year_2026 + 1);
  ASSERT_FALSE(after.ok());
  EXPECT_TRUE(Contains(after.status().message(), "expired")) << after.status().message();
  for (const std::string& wrong :
       {std::string("0123456789abcdef012"), std::string("0123456789abcdef01234"), std::string(),
        std::string("1123456789abcdef0123")}) {
    StatusOr<DeviceToken> refused = table->Authenticate(wrong, 0);
    ASSERT_FALSE(refused.ok()) << wrong;
    EXPECT_EQ(refused.status().message(), "unknown token");
  }
}

TEST(TokenTableTest, ADeviceMayNameItsOwnKey) {
  StatusOr<TokenTable> table = TokenTable::Parse(
      "0123456789abcdef0123 phone-anna key=anna-key\n"
      "fedcba9876543210fedc handheld expires=2099-01-01T00:00:00Z key=shared.key\n"
      "aaaabbbbccccddddeeee robot-far\n");
  ASSERT_TRUE(table.ok()) << table.status().ToString();
  StatusOr<DeviceToken> anna = table->Authenticate("0123456789abcdef0123", 0);
  ASSERT_TRUE(anna.ok());
  EXPECT_EQ(anna->key_id, "anna-key");
  StatusOr<DeviceToken> handheld = table->Authenticate("fedcba9876543210fedc", 0);
  ASSERT_TRUE(handheld.ok());
  EXPECT_EQ(handheld->key_id, "shared.key");
  EXPECT_NE(handheld->expires_unix, 0);
  EXPECT_EQ(table->KeyIds(), (std::set<std::string>{"", "anna-key", "shared.key"}));
}

TEST(TokenTableTest, BadLinesAreRefusedWithTheirNumber) {
  const std::pair<std::string, std::string> cases[] = {
      {"short phone\n", "line 1: the token is shorter than 16"},
      {"\n0123456789abcdef0123\n", "line 2: no device id"},
      {"0123456789abcdef0123 bad/id\n", "line 1: device id: robot id byte 3"},
      {"0123456789abcdef0123 ok expires=tomorrow\n", "line 1: 'expires=tomorrow'"},
      {"0123456789abcdef0123 ok key=\n", "line 1: 'key=': a key id is 1 to 64"},
      {"0123456789abcdef0123 ok key=a/b\n", "line 1: 'key=a/b'"},
      {"0123456789abcdef0123 ok colour=red\n", "neither key=KEY_ID nor expires="},
      {"0123456789abcdef0123 a\n0123456789abcdef0123 b\n", "line 2: this token is listed twice"},
  };
  for (const auto& [text, expected] : cases) {
    StatusOr<TokenTable> table = TokenTable::Parse(text);
    ASSERT_FALSE(table.ok()) << text;
    EXPECT_TRUE(Contains(table.status().message(), expected)) << table.status().message();
  }
  EXPECT_FALSE(TokenTable::Load("/nonexistent/tokens").ok());
}

TEST(RateLimiterTest, ABurstThenTheRatePerToken) {
  RateLimiter limiter(60, 3);  // one a second, bursts of 3
  const RateLimiter::Clock::time_point t0 = RateLimiter::Clock::now();
  double retry = 0;
  for (int i = 0; i < 3; ++i) EXPECT_TRUE(limiter.Allow("a", t0, &retry)) << i;
  EXPECT_FALSE(limiter.Allow("a", t0, &retry));
  EXPECT_NEAR(retry, 1.0, 1e-6);
  EXPECT_TRUE(limiter.Allow("b", t0, &retry));  // another token has its own bucket
  EXPECT_FALSE(limiter.Allow("a", t0 + std::chrono::milliseconds(500), &retry));
  EXPECT_TRUE(limiter.Allow("a", t0 + std::chrono::milliseconds(1100), &retry));
  EXPECT_FALSE(limiter.Allow("a", t0 + std::chrono::milliseconds(1100), &retry));
}

}  // namespace
}  // namespace placerec
