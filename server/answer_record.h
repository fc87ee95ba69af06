// The server's record of recent frames per robot (issue 23 item 7): a client that gets no answer
// sends the same frame again with the same request id; the server must not process it twice (an
// insert would then be refused as out of order, or stored twice). A frame is known by its
// robot, request id, sequence, capture time, insert flag, the key that signed it and its image
// (a digest: a sender that reuses a request id for another image gets that image answered, not
// the earlier one's answer); a resend signed again is the same frame. A frame still queued or
// running is "in flight" (the duplicate is dropped: the answer is on its way, and also to the
// network the duplicate came on when that is another); a processed one keeps its answer, which a
// duplicate gets again. Each robot keeps its last `per_robot` frames; robots beyond `max_robots`
// are not recorded (their duplicates are processed again). Thread-safe.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <initializer_list>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include "placerec/frame_t.hpp"
#include "placerec/result_t.hpp"

namespace placerec {

class AnswerRecord {
 public:
  explicit AnswerRecord(size_t per_robot = 16, size_t max_robots = 1000)
      : per_robot_(per_robot), max_robots_(max_robots) {}

  enum class Seen {
    kNew,       // not recorded: process it (it is now in flight)
    kInFlight,  // the same frame is queued or running: drop this copy
    kAnswered,  // processed before: send *answer again
  };

  // Looks `frame`, received on `network` (an index of the server's networks), up; a new frame is
  // recorded as in flight. A copy of a frame in flight that came on another network is noted:
  // Finish and Forget name that network too.
  Seen Begin(const frame_t& frame, result_t* answer, size_t network = 0) {
    const Key key = Key::Of(frame);  // hashes the image: outside the lock
    std::lock_guard lock(mutex_);
    auto robot = frames_.find(frame.robot);
    if (robot == frames_.end()) {
      if (frames_.size() >= max_robots_) return Seen::kNew;
      robot = frames_.emplace(frame.robot, std::deque<Entry>()).first;
    }
    std::deque<Entry>& entries = robot->second;
    for (Entry& entry : entries) {
      if (!(entry.key == key)) continue;
      if (!entry.answer) {
        if (network != entry.network &&
            std::find(entry.also.begin(), entry.also.end(), network) == entry.also.end()) {
          entry.also.push_back(network);
        }
        return Seen::kInFlight;
      }
      *answer = *entry.answer;
      return Seen::kAnswered;
    }
    entries.push_back(Entry{key, std::nullopt, network, {}});
    // Drop the oldest answered entries beyond the bound; frames in flight always stay.
    for (auto it = entries.begin(); entries.size() > per_robot_ && it != entries.end();) {
      it = it->answer ? entries.erase(it) : std::next(it);
    }
    return Seen::kNew;
  }

  // `frame` (recorded by Begin) was processed: keep its answer for duplicates. Returns the
  // other networks copies of it came on while in flight, which are owed the answer too.
  std::vector<size_t> Finish(const frame_t& frame, const result_t& answer) {
    const Key key = Key::Of(frame);
    std::lock_guard lock(mutex_);
    Entry* entry = Find(frame.robot, key);
    if (entry == nullptr) return {};
    entry->answer = answer;
    return entry->also;
  }

  // A byte-identical copy of an accepted frame (the replay guard's "replayed": not processed,
  // and on the frame's own network not answered) that came on `network`. When the frame came on
  // another network, the copy's network is owed the answer once: kInFlight, noted for Finish;
  // kAnswered, *answer is to be sent there now. kNew: nothing to do (the frame's own network, a
  // network already served, or a frame no longer recorded).
  Seen CopyOnNetwork(const frame_t& frame, size_t network, result_t* answer) {
    const Key key = Key::Of(frame);
    std::lock_guard lock(mutex_);
    Entry* entry = Find(frame.robot, key);
    if (entry == nullptr || network == entry->network ||
        std::find(entry->also.begin(), entry->also.end(), network) != entry->also.end()) {
      return Seen::kNew;
    }
    entry->also.push_back(network);
    if (!entry->answer) return Seen::kInFlight;
    *answer = *entry->answer;
    return Seen::kAnswered;
  }

  // `frame` (recorded by Begin) was not processed (overloaded, shutting down): forget it, so that
  // it is processed when it comes again. Returns the other networks copies of it came on, which
  // are owed the refusal too.
  std::vector<size_t> Forget(const frame_t& frame) {
    const Key key = Key::Of(frame);
    std::lock_guard lock(mutex_);
    const auto robot = frames_.find(frame.robot);
    if (robot == frames_.end()) return {};
    std::vector<size_t> also;
    std::deque<Entry>& entries = robot->second;
    for (auto it = entries.begin(); it != entries.end(); ++it) {
      if (it->key == key) {
        also = std::move(it->also);
        entries.erase(it);
        break;
      }
    }
    if (entries.empty()) frames_.erase(robot);
    return also;
  }

 private:
  struct Key {
    int64_t request_id = 0;
    int64_t sequence = 0;
    int64_t utime = 0;
    bool insert = false;
    // A digest of the image (encoding, size, bytes) and of the signing key's id; not of the
    // signature, counter and signing time, which a resend signed again changes.
    size_t content = 0;
    static Key Of(const frame_t& frame) {
      // LCM keeps a boolean's byte as sent: any byte but 0 is an insert (as the server reads it).
      return Key{frame.request_id, frame.sequence, frame.utime, frame.insert != 0, Digest(frame)};
    }
    static size_t Digest(const frame_t& frame) {
      const std::hash<std::string_view> hash;
      size_t digest = hash(
          std::string_view(reinterpret_cast<const char*>(frame.data.data()), frame.data.size()));
      for (const size_t part :
           {static_cast<size_t>(frame.encoding), static_cast<size_t>(frame.width),
            static_cast<size_t>(frame.height), hash(frame.key_id)}) {
        digest ^= part + 0x9e3779b97f4a7c15ULL + (digest << 6) + (digest >> 2);
      }
      return digest;
    }
    bool operator==(const Key& other) const {
      return request_id == other.request_id && sequence == other.sequence && utime == other.utime &&
             insert == other.insert && content == other.content;
    }
  };
  struct Entry {
    Key key;
    std::optional<result_t> answer;  // empty while in flight
    size_t network = 0;              // the network the frame came on
    std::vector<size_t> also;        // other networks copies came on (answered there too)
  };

  Entry* Find(const std::string& robot_id, const Key& key) {
    const auto robot = frames_.find(robot_id);
    if (robot == frames_.end()) return nullptr;
    for (Entry& entry : robot->second) {
      if (entry.key == key) return &entry;
    }
    return nullptr;
  }

  const size_t per_robot_;
  const size_t max_robots_;
  std::mutex mutex_;
  std::unordered_map<std::string, std::deque<Entry>> frames_;
};

}  // namespace placerec
