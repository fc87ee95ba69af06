// What the gateway's site overview shows (issue 26 item 4): the server's last heartbeat and the
// recent loop closures of every robot, heard on the LCM network (PLACEREC_STATUS and every
// PLACEREC_RESULT_<robot> channel). Thread-safe; listens on a thread of its own.
#pragma once

#include <atomic>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "common/util/status.h"

namespace lcm {
class LCM;
class ReceiveBuffer;
}  // namespace lcm

namespace placerec {

class SiteWatcher {
 public:
  // Listens on `lcm_url` (empty: LCM's default); keeps the last `keep` loop closures.
  static StatusOr<std::unique_ptr<SiteWatcher>> Start(const std::string& lcm_url, size_t keep);
  ~SiteWatcher();

  // {"server": {...heartbeat...} or null, "loop_closures": [{robot, sequence, utime, place:
  // {robot, sequence, utime, place_id, score}}, ...] newest first, "robots": [ids heard]}.
  nlohmann::json Overview() const;
  // The last heartbeat as JSON; null when none was heard yet.
  nlohmann::json LastStatus() const;

 private:
  SiteWatcher(std::unique_ptr<lcm::LCM> lcm, size_t keep);
  void OnResult(const lcm::ReceiveBuffer* buffer, const std::string& channel);
  void OnStatus(const lcm::ReceiveBuffer* buffer, const std::string& channel);

  std::unique_ptr<lcm::LCM> lcm_;
  size_t keep_;
  mutable std::mutex mutex_;
  nlohmann::json status_;
  std::deque<nlohmann::json> loop_closures_;          // newest first
  nlohmann::json robots_ = nlohmann::json::object();  // robot -> frames heard
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace placerec
