#include "proto/auth/signing.h"

#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <sys/stat.h>

#include <cctype>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <set>
#include <sstream>

namespace placerec {

bool IsValidKeyId(const std::string& id) {
  if (id.empty() || id.size() > kMaxKeyIdLength) return false;
  for (unsigned char c : id) {
    if (!std::isalnum(c) && c != '_' && c != '-' && c != '.') return false;
  }
  return true;
}

namespace {

int HexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

bool DecodeHexKey(const std::string& hex, std::string* secret) {
  if (hex.size() != 2 * kKeyBytes) return false;
  secret->clear();
  for (size_t i = 0; i < hex.size(); i += 2) {
    const int high = HexValue(hex[i]);
    const int low = HexValue(hex[i + 1]);
    if (high < 0 || low < 0) return false;
    secret->push_back(static_cast<char>(high * 16 + low));
  }
  return true;
}

}  // namespace

StatusOr<std::vector<SigningKey>> ReadKeysFile(const std::string& path, std::string* warning) {
  warning->clear();
  std::ifstream in(path);
  if (!in) {
    return Status::NotFound("cannot read the keys file " + path +
                            " (make one with scripts/make-key.sh; format: server/README.md "
                            "\"Keys\")");
  }
  struct stat info = {};
  if (stat(path.c_str(), &info) == 0 && (info.st_mode & 077) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof(mode), "%04o", static_cast<unsigned>(info.st_mode & 07777));
    *warning = "the keys file " + path + " has mode " + mode +
               ": group or others may read the secrets; run chmod 600 " + path;
  }
  std::vector<SigningKey> keys;
  std::set<std::string> ids;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    std::istringstream fields(line);
    std::string id, permission, hex, extra;
    if (!(fields >> id) || id[0] == '#') continue;
    const std::string where = path + " line " + std::to_string(number) + ": ";
    if (!(fields >> permission >> hex) || (fields >> extra && extra[0] != '#')) {
      return Status::InvalidArgument(where +
                                     "expected 'ID PERMISSION KEY' (PERMISSION insert, query or "
                                     "both; KEY 64 hex digits)");
    }
    SigningKey key;
    key.id = id;
    if (!IsValidKeyId(id)) {
      return Status::InvalidArgument(where + "key id '" + id + "' must be 1 to " +
                                     std::to_string(kMaxKeyIdLength) +
                                     " ASCII letters, digits, '_', '-' or '.'");
    }
    if (!ids.insert(id).second) {
      return Status::InvalidArgument(where + "key id '" + id + "' appears twice");
    }
    if (permission == "insert") {
      key.may_insert = true;
    } else if (permission == "query") {
      key.may_query = true;
    } else if (permission == "both") {
      key.may_insert = key.may_query = true;
    } else {
      return Status::InvalidArgument(where + "permission '" + permission +
                                     "' is not insert, query or both");
    }
    if (!DecodeHexKey(hex, &key.secret)) {
      return Status::InvalidArgument(where + "the key of '" + id + "' must be " +
                                     std::to_string(2 * kKeyBytes) +
                                     " hex digits (scripts/make-key.sh makes one)");
    }
    keys.push_back(std::move(key));
  }
  return keys;
}

const SigningKey* FindKey(const std::vector<SigningKey>& keys, const std::string& id) {
  for (const SigningKey& key : keys) {
    if (id.empty() || key.id == id) return &key;
  }
  return nullptr;
}

Signature HmacSha256(const std::string& secret, const void* data, size_t size) {
  Signature mac = {};
  unsigned int length = 0;
  HMAC(EVP_sha256(), secret.data(), static_cast<int>(secret.size()),
       static_cast<const unsigned char*>(data), size, mac.data(), &length);
  return mac;
}

std::vector<uint8_t> EncodeFrame(const frame_t& frame) {
  std::vector<uint8_t> bytes(static_cast<size_t>(frame.getEncodedSize()));
  frame.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

std::vector<uint8_t> EncodeAnswer(const result_t& answer) {
  std::vector<uint8_t> bytes(static_cast<size_t>(answer.getEncodedSize()));
  answer.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

void ClearFrameSignature(frame_t* frame) {
  frame->key_id.clear();
  frame->auth_counter = 0;
  frame->auth_utime = 0;
  std::memset(frame->signature, 0, kSignatureBytes);
}

void SignFrame(const SigningKey& key, int64_t counter, int64_t utime, frame_t* frame) {
  frame->key_id = key.id;
  frame->auth_counter = counter;
  frame->auth_utime = utime;
  std::memset(frame->signature, 0, kSignatureBytes);
  const std::vector<uint8_t> bytes = EncodeFrame(*frame);
  const Signature mac = HmacSha256(key.secret, bytes.data(), bytes.size());
  std::memcpy(frame->signature, mac.data(), kSignatureBytes);
}

size_t FrameSignatureOffset(const frame_t& frame) {
  // fingerprint, utime, sequence, request_id, insert, encoding, width, height; then the robot
  // and the key id as LCM strings (int32 length, bytes, NUL); then auth_counter, auth_utime.
  return 8 + 8 + 8 + 8 + 1 + 1 + 4 + 4 + (4 + frame.robot.size() + 1) +
         (4 + frame.key_id.size() + 1) + 8 + 8;
}

bool FrameSignatureValid(const frame_t& frame, const std::string& secret, const void* received,
                         size_t size) {
  std::vector<uint8_t> bytes;
  if (received != nullptr) {
    const size_t offset = FrameSignatureOffset(frame);
    if (offset + kSignatureBytes > size ||
        std::memcmp(static_cast<const uint8_t*>(received) + offset, frame.signature,
                    kSignatureBytes) != 0) {
      return false;  // not the bytes `frame` was decoded from
    }
    bytes.assign(static_cast<const uint8_t*>(received),
                 static_cast<const uint8_t*>(received) + size);
    std::memset(bytes.data() + offset, 0, kSignatureBytes);
  } else {
    frame_t zeroed = frame;
    std::memset(zeroed.signature, 0, kSignatureBytes);
    bytes = EncodeFrame(zeroed);
  }
  const Signature mac = HmacSha256(secret, bytes.data(), bytes.size());
  return CRYPTO_memcmp(mac.data(), frame.signature, kSignatureBytes) == 0;
}

bool FrameIsUnsigned(const frame_t& frame) {
  if (!frame.key_id.empty()) return false;
  for (size_t i = 0; i < kSignatureBytes; ++i) {
    if (frame.signature[i] != 0) return false;
  }
  return true;
}

void ClearAnswerSignature(result_t* answer) {
  answer->key_id.clear();
  std::memset(answer->signature, 0, kSignatureBytes);
}

void SignAnswer(const SigningKey& key, result_t* answer) {
  answer->key_id = key.id;
  std::memset(answer->signature, 0, kSignatureBytes);
  const std::vector<uint8_t> bytes = EncodeAnswer(*answer);
  const Signature mac = HmacSha256(key.secret, bytes.data(), bytes.size());
  std::memcpy(answer->signature, mac.data(), kSignatureBytes);
}

bool AnswerSignatureValid(const result_t& answer, const SigningKey& key, const void* received,
                          size_t size) {
  if (answer.key_id != key.id) return false;
  if (received != nullptr) {
    const std::vector<uint8_t> canonical = EncodeAnswer(answer);
    if (canonical.size() != size || std::memcmp(canonical.data(), received, size) != 0) {
      return false;  // bytes LCM's decoder skips (a string's NUL) were changed
    }
  }
  result_t zeroed = answer;
  std::memset(zeroed.signature, 0, kSignatureBytes);
  const std::vector<uint8_t> bytes = EncodeAnswer(zeroed);
  const Signature mac = HmacSha256(key.secret, bytes.data(), bytes.size());
  return CRYPTO_memcmp(mac.data(), answer.signature, kSignatureBytes) == 0;
}

}  // namespace placerec
