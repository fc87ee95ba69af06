// Counters the server reports in its heartbeat (status_t): answers by kind, dropped messages,
// robots seen, and the frame rate over a sliding window. Thread-safe.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <mutex>
#include <set>
#include <string>

namespace placerec {

class ServerStats {
 public:
  explicit ServerStats(double window_s = 10.0) : window_s_(window_s), start_(Clock::now()) {}

  // One answer was published; `processed` when a worker ran the frame (not for answers given
  // straight from the receive thread), `failed` for any error status.
  void Answered(bool processed, bool failed, bool overloaded) {
    std::lock_guard lock(mutex_);
    ++answered_;
    if (failed) ++failed_;
    if (overloaded) ++overloaded_;
    if (processed) {
      const Clock::time_point now = Clock::now();
      done_.push_back(now);
      Trim(now);
    }
  }
  void Dropped() {
    std::lock_guard lock(mutex_);
    ++dropped_;
  }
  // Remembers a robot id (up to a bound, so that a flood of ids cannot grow memory).
  void SawRobot(const std::string& robot) {
    std::lock_guard lock(mutex_);
    if (robots_.size() < kMaxRobots) robots_.insert(robot);
  }

  struct Snapshot {
    double uptime_s = 0;
    int64_t answered = 0;
    int64_t failed = 0;
    int64_t overloaded = 0;
    int64_t dropped = 0;
    int robots = 0;
    double frames_per_second = 0;
  };
  Snapshot Take() {
    std::lock_guard lock(mutex_);
    const Clock::time_point now = Clock::now();
    Trim(now);
    Snapshot s;
    s.uptime_s = std::chrono::duration<double>(now - start_).count();
    s.answered = answered_;
    s.failed = failed_;
    s.overloaded = overloaded_;
    s.dropped = dropped_;
    s.robots = static_cast<int>(robots_.size());
    const double span = s.uptime_s < window_s_ ? s.uptime_s : window_s_;
    s.frames_per_second = span > 0 ? done_.size() / span : 0.0;
    return s;
  }

 private:
  using Clock = std::chrono::steady_clock;
  static constexpr size_t kMaxRobots = 100000;

  void Trim(Clock::time_point now) {
    const auto window = std::chrono::duration<double>(window_s_);
    while (!done_.empty() && now - done_.front() > window) done_.pop_front();
  }

  const double window_s_;
  const Clock::time_point start_;
  std::mutex mutex_;
  int64_t answered_ = 0;
  int64_t failed_ = 0;
  int64_t overloaded_ = 0;
  int64_t dropped_ = 0;
  std::set<std::string> robots_;
  std::deque<Clock::time_point> done_;  // when each processed frame was answered, in the window
};

}  // namespace placerec
