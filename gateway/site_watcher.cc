#include "gateway/site_watcher.h"

#include <algorithm>
#include <chrono>

#include <lcm/lcm-cpp.hpp>

#include "placerec/change_t.hpp"
#include "placerec/result_t.hpp"
#include "placerec/status_t.hpp"
#include "proto/channels.h"
#include "proto/decode.h"

namespace placerec {

StatusOr<std::unique_ptr<SiteWatcher>> SiteWatcher::Start(const std::string& lcm_url, size_t keep,
                                                          std::set<std::string> hidden_robots) {
  auto lcm = std::make_unique<lcm::LCM>(lcm_url);
  if (!lcm->good()) {
    return Status::IoError("cannot open LCM" + (lcm_url.empty() ? "" : " at " + lcm_url));
  }
  std::unique_ptr<SiteWatcher> watcher(
      new SiteWatcher(std::move(lcm), keep, std::move(hidden_robots)));
  lcm::Subscription* results = watcher->lcm_->subscribe(std::string(kResultChannelPrefix) + ".*",
                                                        &SiteWatcher::OnResult, watcher.get());
  lcm::Subscription* status =
      watcher->lcm_->subscribe(kStatusChannel, &SiteWatcher::OnStatus, watcher.get());
  lcm::Subscription* changes =
      watcher->lcm_->subscribe(kChangeChannel, &SiteWatcher::OnChange, watcher.get());
  if (results == nullptr || status == nullptr || changes == nullptr) {
    return Status::IoError("cannot subscribe on LCM");
  }
  SiteWatcher* self = watcher.get();
  watcher->thread_ = std::thread([self] {
    while (!self->stop_) self->lcm_->handleTimeout(100);
  });
  return watcher;
}

SiteWatcher::SiteWatcher(std::unique_ptr<lcm::LCM> lcm, size_t keep,
                         std::set<std::string> hidden_robots)
    : lcm_(std::move(lcm)),
      keep_(keep),
      hidden_robots_(std::move(hidden_robots)),
      next_alarm_id_(std::chrono::duration_cast<std::chrono::milliseconds>(
                         std::chrono::system_clock::now().time_since_epoch())
                         .count()) {}

SiteWatcher::~SiteWatcher() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

void SiteWatcher::OnResult(const lcm::ReceiveBuffer* buffer, const std::string&) {
  result_t answer;
  if (DecodeLcmMessage(buffer->data, buffer->data_size, &answer)) Hear(answer);
}

void SiteWatcher::OnStatus(const lcm::ReceiveBuffer* buffer, const std::string&) {
  status_t status;
  if (DecodeLcmMessage(buffer->data, buffer->data_size, &status)) Hear(status);
}

void SiteWatcher::OnChange(const lcm::ReceiveBuffer* buffer, const std::string&) {
  change_t change;
  if (DecodeLcmMessage(buffer->data, buffer->data_size, &change)) Hear(change);
}

void SiteWatcher::Hear(const result_t& answer) {
  std::string why;
  if (!IsValidWireRobotId(answer.robot, &why)) return;
  std::lock_guard lock(mutex_);
  if (hidden_robots_.count(answer.robot) > 0) return;
  if (robots_.contains(answer.robot)) {
    robots_[answer.robot] = robots_[answer.robot].get<int64_t>() + 1;
  } else if (robots_.size() < kMaxRobots) {
    robots_[answer.robot] = 1;
  }
  if (answer.status != result_t::STATUS_OK || !answer.loop_closure || answer.matches.empty()) {
    return;
  }
  const match_t& best = answer.matches.front();
  loop_closures_.push_front({{"robot", answer.robot},
                             {"sequence", answer.sequence},
                             {"utime", answer.frame_utime},
                             {"insert", answer.insert},
                             {"place",
                              {{"robot", best.robot},
                               {"sequence", best.sequence},
                               {"utime", best.utime},
                               {"place_id", best.place_id},
                               {"score", best.score}}}});
  while (loop_closures_.size() > keep_) loop_closures_.pop_back();
}

void SiteWatcher::Hear(const status_t& s) {
  std::lock_guard lock(mutex_);
  status_ = {{"version", s.version},
             {"uptime_s", s.uptime_s},
             {"map_places", s.map_places},
             {"map_landmarks", s.map_landmarks},
             {"map_descriptors", s.map_descriptors},
             {"queue_depth", s.queue_depth},
             {"queue_capacity", s.queue_capacity},
             {"workers", s.workers},
             {"robots", s.robots},
             {"frames_answered", s.frames_answered},
             {"frames_per_second", s.frames_per_second}};
}

void SiteWatcher::Hear(const change_t& c) {
  std::string why;
  if (!IsValidWireRobotId(c.robot, &why)) return;
  std::lock_guard lock(mutex_);
  if (hidden_robots_.count(c.robot) > 0) return;
  Alarm alarm;
  alarm.id = next_alarm_id_++;
  const std::string pictures = "/v1/alarms/" + std::to_string(alarm.id);
  alarm.summary = {
      {"id", alarm.id},
      {"robot", c.robot},
      {"sequence", c.sequence},
      {"utime", c.frame_utime},
      {"kind", c.kind == change_t::KIND_DISAPPEARED ? "disappeared" : "appeared"},
      {"class", c.object_class},
      {"confidence", c.confidence},
      {"box", {{"x", c.box[0]}, {"y", c.box[1]}, {"width", c.box[2]}, {"height", c.box[3]}}},
      {"place",
       {{"place_id", c.place_id},
        {"robot", c.place_robot},
        {"sequence", c.place_sequence},
        {"utime", c.place_utime}}},
      {"frame_picture", c.frame_jpeg.empty() ? "" : pictures + "/frame.jpg"},
      {"place_picture", c.place_jpeg.empty() ? "" : pictures + "/place.jpg"}};
  alarm.frame_jpeg = c.frame_jpeg;
  alarm.place_jpeg = c.place_jpeg;
  alarms_.push_front(std::move(alarm));
  while (alarms_.size() > keep_) alarms_.pop_back();
}

void SiteWatcher::HideRobots(const std::set<std::string>& robots) {
  std::lock_guard lock(mutex_);
  for (const std::string& robot : robots) {
    hidden_robots_.insert(robot);
    robots_.erase(robot);
  }
  const auto hidden = [&](const nlohmann::json& entry) {
    return robots.count(entry["robot"].get<std::string>()) > 0;
  };
  loop_closures_.erase(std::remove_if(loop_closures_.begin(), loop_closures_.end(), hidden),
                       loop_closures_.end());
  alarms_.erase(std::remove_if(alarms_.begin(), alarms_.end(),
                               [&](const Alarm& alarm) { return hidden(alarm.summary); }),
                alarms_.end());
}

bool SiteWatcher::AlarmPicture(int64_t id, bool place, std::vector<uint8_t>* jpeg) const {
  std::lock_guard lock(mutex_);
  for (const Alarm& alarm : alarms_) {
    if (alarm.id != id) continue;
    *jpeg = place ? alarm.place_jpeg : alarm.frame_jpeg;
    return true;
  }
  return false;
}

nlohmann::json SiteWatcher::LastStatus() const {
  std::lock_guard lock(mutex_);
  return status_;
}

nlohmann::json SiteWatcher::Overview() const {
  std::lock_guard lock(mutex_);
  nlohmann::json alarms = nlohmann::json::array();
  for (const Alarm& alarm : alarms_) alarms.push_back(alarm.summary);
  nlohmann::json robots = nlohmann::json::array();
  for (const auto& [robot, frames] : robots_.items()) {
    robots.push_back({{"robot", robot}, {"frames", frames}});
  }
  return {{"server", status_},
          {"loop_closures", nlohmann::json(std::vector<nlohmann::json>(loop_closures_.begin(),
                                                                       loop_closures_.end()))},
          {"robots", robots},
          {"alarms", alarms}};
}

}  // namespace placerec
