#include "gateway/access.h"

#include <openssl/crypto.h>
#include <sys/stat.h>

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <iomanip>
#include <set>
#include <sstream>

#include "common/util/logging.h"
#include "proto/auth/signing.h"
#include "proto/channels.h"

namespace placerec {
namespace {

// "YYYY-MM-DDTHH:MM:SSZ" as seconds since the epoch (UTC).
bool ParseUtc(const std::string& text, int64_t* unix_s) {
  std::tm tm = {};
  std::istringstream in(text);
  in >> std::get_time(&tm, "%Y-%m-%dT%H:%M:%SZ");
  if (in.fail() || in.peek() != EOF) return false;
  *unix_s = static_cast<int64_t>(timegm(&tm));
  return true;
}

}  // namespace

StatusOr<TokenTable> TokenTable::Parse(const std::string& text) {
  TokenTable table;
  std::set<std::string> seen;
  std::istringstream lines(text);
  std::string line;
  for (int number = 1; std::getline(lines, line); ++number) {
    std::istringstream fields(line);
    DeviceToken entry;
    if (!(fields >> entry.token) || entry.token[0] == '#') continue;
    const std::string where = "tokens line " + std::to_string(number) + ": ";
    if (entry.token.size() < 16) {
      return Status::InvalidArgument(where +
                                     "the token is shorter than 16 characters; use e.g. "
                                     "`openssl rand -hex 24`");
    }
    for (const char c : entry.token) {
      if (c <= 0x20 || c >= 0x7f) {
        return Status::InvalidArgument(where + "a token is printable ASCII without spaces");
      }
    }
    if (!(fields >> entry.device)) {
      return Status::InvalidArgument(where +
                                     "no device id after the token (TOKEN DEVICE "
                                     "[key=KEY_ID] [expires=YYYY-MM-DDTHH:MM:SSZ])");
    }
    std::string why;
    if (!IsValidWireRobotId(entry.device, &why)) {
      return Status::InvalidArgument(where + "device id: " + why);
    }
    std::string option;
    while (fields >> option) {
      if (option.rfind("key=", 0) == 0) {
        entry.key_id = option.substr(4);
        if (!IsValidKeyId(entry.key_id)) {
          return Status::InvalidArgument(where + "'" + option +
                                         "': a key id is 1 to 64 ASCII letters, digits, '_', "
                                         "'-' or '.'");
        }
      } else if (option.rfind("expires=", 0) != 0 ||
                 !ParseUtc(option.substr(8), &entry.expires_unix)) {
        return Status::InvalidArgument(where + "'" + option +
                                       "' is neither key=KEY_ID nor expires=YYYY-MM-DDTHH:MM:SSZ");
      }
    }
    if (!seen.insert(entry.token).second) {
      return Status::InvalidArgument(where + "this token is listed twice");
    }
    table.tokens_.push_back(std::move(entry));
  }
  return table;
}

StatusOr<TokenTable> TokenTable::Load(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Status::NotFound("cannot read the tokens file " + path);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  StatusOr<TokenTable> table = Parse(text);
  if (!table.ok()) return Status::InvalidArgument(path + ": " + table.status().message());
  struct stat info = {};
  if (stat(path.c_str(), &info) == 0 && (info.st_mode & 077) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof(mode), "%04o", static_cast<unsigned>(info.st_mode & 07777));
    LOG(WARNING) << "the tokens file " << path << " has mode " << mode
                 << ": group or others have access to the tokens; run chmod 600 " << path;
  }
  return table;
}

StatusOr<DeviceToken> TokenTable::Authenticate(const std::string& token, int64_t now_unix) const {
  const DeviceToken* found = nullptr;
  for (const DeviceToken& entry : tokens_) {
    // Every entry is compared, each in constant time, so the time taken tells nothing.
    const bool same = entry.token.size() == token.size() &&
                      CRYPTO_memcmp(entry.token.data(), token.data(), token.size()) == 0;
    if (same) found = &entry;
  }
  if (found == nullptr) return Status::InvalidArgument("unknown token");
  if (found->expires_unix != 0 && now_unix > found->expires_unix) {
    return Status::InvalidArgument("the token of device '" + found->device +
                                   "' has expired; ask the site's operator for a new one");
  }
  return *found;
}

std::set<std::string> TokenTable::KeyIds() const {
  std::set<std::string> ids;
  for (const DeviceToken& entry : tokens_) ids.insert(entry.key_id);
  return ids;
}

std::set<std::string> TokenTable::Devices() const {
  std::set<std::string> ids;
  for (const DeviceToken& entry : tokens_) ids.insert(entry.device);
  return ids;
}

bool RateLimiter::Allow(const std::string& key, Clock::time_point now, double* retry_after_s) {
  std::lock_guard lock(mutex_);
  auto [it, inserted] = buckets_.try_emplace(key);
  Bucket& bucket = it->second;
  if (inserted) {
    bucket.tokens = burst_;
  } else {
    const double elapsed = std::chrono::duration<double>(now - bucket.updated).count();
    bucket.tokens = std::min(burst_, bucket.tokens + std::max(0.0, elapsed) * per_second_);
  }
  bucket.updated = now;
  if (bucket.tokens >= 1.0) {
    bucket.tokens -= 1.0;
    return true;
  }
  *retry_after_s = per_second_ > 0 ? (1.0 - bucket.tokens) / per_second_ : 60.0;
  return false;
}

}  // namespace placerec
