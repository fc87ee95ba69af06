#include "server/authenticator.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <utility>

namespace placerec {
namespace {

// Counters remembered per key at most; beyond, the smallest are forgotten (the floor rises), so a
// flood under one key costs bounded memory (100,000 frames a window is over 3,000 per second).
constexpr size_t kMaxRememberedCounters = 100000;

const char kUnsignedAdvice[] =
    "unsigned frame: this server accepts only frames signed with a key from its keys file; give "
    "the client a key file (placerec-client --key-file FILE, keys from the server's operator: "
    "scripts/make-key.sh, server/README.md \"Keys\"), or run the server with --auth off on a lab "
    "LAN";

}  // namespace

bool AuthOptions::Check(std::string* error) const {
  if (!(window_s > 0) || window_s > 3600) {
    *error = "--auth-window must be positive and at most 3600 seconds";
    return false;
  }
  return true;
}

std::string MissingKeysAdvice() {
  return "authentication is on and no keys file was given: give --keys FILE (one line per robot "
         "or device: 'ID insert|query|both KEY'; scripts/make-key.sh ID PERMISSION >> FILE makes "
         "a key; server/README.md \"Keys\"), or start with --auth off on a lab LAN only";
}

StatusOr<Authenticator> Authenticator::Create(const AuthOptions& options, int64_t start_utime) {
  std::string error;
  if (!options.Check(&error)) return Status::InvalidArgument(error);
  if (options.enabled && options.keys_file.empty()) {
    return Status::InvalidArgument(MissingKeysAdvice());
  }
  Authenticator auth(options, start_utime);
  if (options.enabled) PLACEREC_RETURN_IF_ERROR(auth.Reload());
  return auth;
}

Status Authenticator::Reload() {
  std::string warning;
  StatusOr<std::vector<SigningKey>> keys = ReadKeysFile(options_.keys_file, &warning);
  if (!keys.ok()) return keys.status();
  if (keys->empty()) {
    return Status::InvalidArgument("the keys file " + options_.keys_file +
                                   " holds no key; add one (scripts/make-key.sh ID PERMISSION >> " +
                                   options_.keys_file + ")");
  }
  std::map<std::string, ReplayState> replay;
  for (auto& [id, state] : replay_) {
    const SigningKey* key = FindKey(*keys, id);
    // A new secret starts afresh: frames signed with the old one no longer verify.
    if (key != nullptr && key->secret != state.secret) continue;
    if (key == nullptr) {
      // Removed: kept while it holds counters of the window (older frames are refused for
      // their time anyway), in case the key comes back.
      Forget(&state, last_check_utime_);
      if (state.counters.empty()) continue;
    }
    replay.emplace(id, std::move(state));
  }
  keys_ = std::move(*keys);
  replay_ = std::move(replay);
  warning_ = warning;
  return Status::Ok();
}

void Authenticator::Forget(ReplayState* state, int64_t now_utime) const {
  const int64_t oldest = now_utime - static_cast<int64_t>(options_.window_s * 1e6);
  // Counters follow their signers' clocks (placerec's client starts them from it), so the
  // oldest come first: the walk stops at the first counter still in the window, and a frame
  // costs the counters it forgets, not all those remembered. A later counter signed earlier
  // (another signer's clock behind) is forgotten once the counters before it are.
  for (auto it = state->counters.begin(); it != state->counters.end();
       it = state->counters.erase(it)) {
    if (it->second.utime >= oldest && state->counters.size() <= kMaxRememberedCounters) break;
    state->floor = std::max(state->floor, it->first);
  }
}

Authenticator::Verdict Authenticator::Check(const frame_t& frame, int64_t now_utime,
                                            const void* received, size_t size) {
  Verdict verdict;
  if (!options_.enabled) {
    verdict.ok = true;
    return verdict;
  }
  if (FrameIsUnsigned(frame)) {
    verdict.message = kUnsignedAdvice;
    return verdict;
  }
  const SigningKey* key = FindKey(keys_, frame.key_id);
  if (frame.key_id.empty() || key == nullptr) {
    verdict.message = "unknown key id '" + frame.key_id.substr(0, kMaxKeyIdLength) +
                      "': the server's keys file has no such key; ask its operator to add "
                      "yours (then SIGHUP reloads it), or use a key it has";
    return verdict;
  }
  if (!FrameSignatureValid(frame, key->secret, received, size)) {
    verdict.message = "the signature does not match key '" + key->id +
                      "': the frame was signed with another key or changed on the way; sign it "
                      "with the key the server has under that id";
    return verdict;
  }
  verdict.key = *key;  // from here on the sender is known: its answer is signed
  const int64_t window_us = static_cast<int64_t>(options_.window_s * 1e6);
  // Compared without a difference that could overflow: auth_utime may be any 64-bit value.
  if (frame.auth_utime < now_utime - window_us || frame.auth_utime > now_utime + window_us) {
    // Positive: signed ahead of the server's clock (the sender's clock is fast).
    const double ahead_s =
        (static_cast<double>(frame.auth_utime) - static_cast<double>(now_utime)) / 1e6;
    char off[32];
    std::snprintf(off, sizeof(off), "%.0f", std::abs(ahead_s));
    verdict.message = "the frame's signing time is " + std::string(off) + " s " +
                      (ahead_s > 0 ? "ahead of" : "behind") +
                      " the server's clock, outside its window of " +
                      std::to_string(window_us / 1000000) +
                      " s: a replay, or the clocks differ; synchronise the clocks (NTP) and send "
                      "it again";
    return verdict;
  }
  if (frame.auth_utime < start_utime_) {
    verdict.message =
        "the frame was signed before the server started (counters of earlier runs are not "
        "remembered, so it may be a replay); send it again, signed now";
    return verdict;
  }
  last_check_utime_ = std::max(last_check_utime_, now_utime);
  auto [found, created] = replay_.try_emplace(key->id);
  ReplayState& state = found->second;
  if (created) state.secret = key->secret;
  Forget(&state, now_utime);
  uint64_t signature = 0;
  std::memcpy(&signature, frame.signature, sizeof(signature));
  const auto used = state.counters.find(frame.auth_counter);
  if (frame.auth_counter <= state.floor || used != state.counters.end()) {
    verdict.replayed = used != state.counters.end() && used->second.signature == signature;
    verdict.message =
        used != state.counters.end()
            ? "replayed frame: key '" + key->id + "' already used counter " +
                  std::to_string(frame.auth_counter)
            : "counter " + std::to_string(frame.auth_counter) + " of key '" + key->id +
                  "' is not above " + std::to_string(state.floor) +
                  ", the highest counter the server no longer remembers (it may be a replay)";
    verdict.message +=
        "; every frame needs a new, increasing counter (send it again signed anew, e.g. with "
        "the signing time in microseconds as its counter; placerec's client does this itself)";
    return verdict;
  }
  if (frame.insert && !key->may_insert) {
    verdict.message = "key '" + key->id +
                      "' may only query: send the frame as a query (insert false), or ask the "
                      "server's operator for a key that may insert";
    return verdict;
  }
  if (!frame.insert && !key->may_query) {
    verdict.message =
        "key '" + key->id + "' may only insert: ask the server's operator for a key that may query";
    return verdict;
  }
  state.counters.emplace(frame.auth_counter, ReplayState::Used{frame.auth_utime, signature});
  verdict.ok = true;
  return verdict;
}

std::vector<std::string> Authenticator::KeyIds() const {
  std::vector<std::string> ids;
  for (const SigningKey& key : keys_) ids.push_back(key.id);
  return ids;
}

}  // namespace placerec
