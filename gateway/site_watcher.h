// What the gateway's site overview shows (issue 26 item 4): the server's last heartbeat, the
// recent loop closures of every robot and the recent scene-change alarms, heard on the LCM
// network (PLACEREC_STATUS, every PLACEREC_RESULT_<robot> channel and PLACEREC_CHANGE).
// Thread-safe; listens on a thread of its own.
#pragma once

#include <atomic>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/util/status.h"

namespace lcm {
class LCM;
class ReceiveBuffer;
}  // namespace lcm

namespace placerec {

class change_t;
class result_t;
class status_t;

class SiteWatcher {
 public:
  // Listens on `lcm_url` (empty: LCM's default); keeps the last `keep` loop closures and the
  // last `keep` alarms (with their two small pictures). The answers and alarms of
  // `hidden_robots` (the gateway's own devices: where a person asked from, and their photo) are
  // not kept, so that no device sees where another one is.
  static StatusOr<std::unique_ptr<SiteWatcher>> Start(const std::string& lcm_url, size_t keep,
                                                      std::set<std::string> hidden_robots = {});
  ~SiteWatcher();

  // {"server": {...heartbeat...} or null, "loop_closures": [{robot, sequence, utime, place:
  // {robot, sequence, utime, place_id, score}}, ...] newest first, "robots": [ids heard],
  // "alarms": [{id, robot, sequence, utime, kind, class, confidence, box, place: {place_id,
  // robot, sequence, utime}, frame_picture, place_picture}, ...] newest first}.
  nlohmann::json Overview() const;
  // The frame's (or, with `place`, the stored place's) JPEG of the recent alarm `id`; false when
  // it is no longer kept.
  bool AlarmPicture(int64_t id, bool place, std::vector<uint8_t>* jpeg) const;
  // The last heartbeat as JSON; null when none was heard yet.
  nlohmann::json LastStatus() const;
  // Hides `robots` too from now on (devices added to the gateway's tokens file), and forgets
  // what was kept of them.
  void HideRobots(const std::set<std::string>& robots);

  // What the watcher does with each message heard (public for tests). Anybody on the LCM network
  // can publish, so messages from a robot id the server would refuse are ignored, and at most
  // kMaxRobots robots are counted. (A stored place's robot comes from the map, which may hold
  // ids of older rules: shown as it is, bytes that are no UTF-8 replaced when printed.)
  void Hear(const result_t& answer);
  void Hear(const status_t& status);
  void Hear(const change_t& change);

  static constexpr size_t kMaxRobots = 1000;

 private:
  SiteWatcher(std::unique_ptr<lcm::LCM> lcm, size_t keep, std::set<std::string> hidden_robots);
  void OnResult(const lcm::ReceiveBuffer* buffer, const std::string& channel);
  void OnStatus(const lcm::ReceiveBuffer* buffer, const std::string& channel);
  void OnChange(const lcm::ReceiveBuffer* buffer, const std::string& channel);

  struct Alarm {
    int64_t id = 0;
    nlohmann::json summary;  // as Overview lists it
    std::vector<uint8_t> frame_jpeg;
    std::vector<uint8_t> place_jpeg;
  };

  std::unique_ptr<lcm::LCM> lcm_;
  size_t keep_;
  mutable std::mutex mutex_;
  std::set<std::string> hidden_robots_;  // guarded by mutex_
  nlohmann::json status_;
  std::deque<nlohmann::json> loop_closures_;          // newest first
  nlohmann::json robots_ = nlohmann::json::object();  // robot -> frames heard
  std::deque<Alarm> alarms_;                          // newest first
  // Alarm ids begin at the start's wall-clock time in milliseconds, so that an open page's
  // pictures of an earlier run's alarm never stand for a new alarm after a restart.
  int64_t next_alarm_id_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace placerec
