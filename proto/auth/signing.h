// Signed frames and answers (protocol 4, proto/README.md "Signed frames"): the keys file, and the
// HMAC-SHA256 (OpenSSL) that signs and checks a frame_t or a result_t. Shared by the server's
// authentication (server/authenticator.h) and the client library, so both compute the signature
// alike. The signature covers the whole encoded message, fingerprint included, with its own 32
// bytes zero; because LCM's encoding is canonical, a receiver re-encodes what it decoded with the
// signature zeroed and compares.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "common/util/status.h"
#include "placerec/frame_t.hpp"
#include "placerec/result_t.hpp"

namespace placerec {

// Bytes of an HMAC-SHA256 and of a key's secret.
inline constexpr size_t kSignatureBytes = 32;
inline constexpr size_t kKeyBytes = 32;
// Longest key id (bytes): ASCII letters, digits, '_', '-', '.'.
inline constexpr size_t kMaxKeyIdLength = 64;

using Signature = std::array<uint8_t, kSignatureBytes>;

// 1 to kMaxKeyIdLength bytes, each an ASCII letter, digit, '_', '-' or '.'.
bool IsValidKeyId(const std::string& id);

// One line of a keys file: who may do what with which secret.
struct SigningKey {
  std::string id;      // named in frame_t::key_id
  std::string secret;  // kKeyBytes raw bytes
  bool may_insert = false;
  bool may_query = false;
};

// Reads a keys file: one key per line, "ID PERMISSION KEY" separated by blanks, where
// PERMISSION is insert, query or both and KEY is 64 hex digits (32 bytes, e.g. from
// scripts/make-key.sh); blank lines and lines starting with '#' are skipped. Ids are unique.
// Errors name the file and line. When group or others may read the file, *warning says so and
// how to fix it (the keys still load); empty otherwise.
StatusOr<std::vector<SigningKey>> ReadKeysFile(const std::string& path, std::string* warning);

// The key with `id` among `keys`, or the first one when `id` is empty; nullptr when none.
const SigningKey* FindKey(const std::vector<SigningKey>& keys, const std::string& id);

// HMAC-SHA256 of `size` bytes keyed with `secret`.
Signature HmacSha256(const std::string& secret, const void* data, size_t size);

// Sets a frame's protocol-4 fields to "unsigned": key_id empty, counter and time 0, signature 0.
void ClearFrameSignature(frame_t* frame);
// Signs `frame` with `key`: sets key_id, auth_counter, auth_utime and the signature.
void SignFrame(const SigningKey& key, int64_t counter, int64_t utime, frame_t* frame);
// Whether `frame`'s signature is the HMAC under `secret` (constant time) of the bytes it was
// decoded from (`received`, `size`; every byte counts) or, when `received` is null, of its
// encoding.
bool FrameSignatureValid(const frame_t& frame, const std::string& secret,
                         const void* received = nullptr, size_t size = 0);
// Where frame_t's signature starts in the encoding of `frame` (bytes from the fingerprint).
size_t FrameSignatureOffset(const frame_t& frame);
// Whether the frame carries no signature at all (no key id, signature all zero).
bool FrameIsUnsigned(const frame_t& frame);

// Sets an answer's protocol-4 fields to "unsigned".
void ClearAnswerSignature(result_t* answer);
// Signs `answer` with `key` (key_id and signature).
void SignAnswer(const SigningKey& key, result_t* answer);
// Whether `answer` is signed with `key` and its signature is valid; with `received` (the bytes
// it was decoded from), also that they are exactly its encoding, so every byte counts.
bool AnswerSignatureValid(const result_t& answer, const SigningKey& key,
                          const void* received = nullptr, size_t size = 0);

// The message bytes as LCM encodes them.
std::vector<uint8_t> EncodeFrame(const frame_t& frame);
std::vector<uint8_t> EncodeAnswer(const result_t& answer);

}  // namespace placerec
