// Wall-clock timing of pipeline stages, in milliseconds.
#pragma once

#include <chrono>
#include <string>
#include <utility>
#include <vector>

namespace placerec {

class Timer {
 public:
  Timer() : start_(Clock::now()) {}
  void Restart() { start_ = Clock::now(); }
  double ElapsedMs() const {
    return std::chrono::duration<double, std::milli>(Clock::now() - start_).count();
  }

 private:
  using Clock = std::chrono::steady_clock;
  Clock::time_point start_;
};

// Named stage durations in the order they ran, e.g. {"sift", 41.2}, {"segmentation", 18.0}.
using StageTimings = std::vector<std::pair<std::string, double>>;

}  // namespace placerec
