// Who may use the HTTPS gateway and how often (issue 26 item 3): per-device bearer tokens and a
// request-rate limit per token.
#pragma once

#include <chrono>
#include <cstdint>
#include <mutex>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

#include "common/util/status.h"

namespace placerec {

// A device allowed to query through the gateway.
struct DeviceToken {
  std::string token;   // the bearer token, at least 16 printable ASCII characters
  std::string device;  // the device's id: its frames' robot id (proto/README.md rule)
  // The key of the gateway's keys file that signs this device's queries (server/README.md
  // "Keys"); empty: the gateway's own key (--key-id). A key per device lets the server's keys
  // file revoke one device alone.
  std::string key_id;
  int64_t expires_unix = 0;  // seconds since the epoch after which the token is refused; 0 never
};

// The tokens file: one device per line, `TOKEN DEVICE [key=KEY_ID] [expires=YYYY-MM-DDTHH:MM:SSZ]`;
// blank lines and lines starting with '#' are ignored.
class TokenTable {
 public:
  // InvalidArgument naming the line and what to fix: a short token, a device id that cannot be
  // a robot id, a malformed key id or expiry, a token listed twice.
  static StatusOr<TokenTable> Parse(const std::string& text);
  static StatusOr<TokenTable> Load(const std::string& path);

  // The device of `token` at `now_unix`; InvalidArgument saying whether it is unknown or expired
  // (the gateway answers 401 with the message). Tokens are compared in constant time.
  StatusOr<DeviceToken> Authenticate(const std::string& token, int64_t now_unix) const;

  size_t size() const { return tokens_.size(); }
  // The distinct key ids the devices name ("" for devices signed with the gateway's own key).
  std::set<std::string> KeyIds() const;
  // The devices' ids.
  std::set<std::string> Devices() const;

 private:
  std::vector<DeviceToken> tokens_;
};

// The token bucket of each key (a token): `per_minute` requests a minute on average, bursts of
// up to `burst`. Thread-safe.
class RateLimiter {
 public:
  using Clock = std::chrono::steady_clock;
  RateLimiter(double per_minute, double burst) : per_second_(per_minute / 60.0), burst_(burst) {}

  // Takes one request of `key` at `now`; false when its bucket is empty, with the seconds until
  // the next request would be allowed in *retry_after_s.
  bool Allow(const std::string& key, Clock::time_point now, double* retry_after_s);

 private:
  struct Bucket {
    double tokens = 0;
    Clock::time_point updated;
  };
  double per_second_;
  double burst_;
  std::mutex mutex_;
  std::unordered_map<std::string, Bucket> buckets_;
};

}  // namespace placerec
