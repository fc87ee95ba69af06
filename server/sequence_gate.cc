#include "server/sequence_gate.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace placerec {

bool SequenceRuleOptions::Check(std::string* error) const {
  if (!(restart_gap_s >= 0) || restart_gap_s > 86400) {
    *error = "--robot-restart-gap must be between 0 and 86400 seconds";
    return false;
  }
  if (max_robot_runs < 1) {
    *error = "--max-robot-runs must be at least 1";
    return false;
  }
  return true;
}

void SequenceGate::AddStored(const std::string& robot, int64_t sequence) {
  std::lock_guard lock(mutex_);
  auto [it, added] = robots_.try_emplace(robot);
  Robot& r = it->second;
  if (added || sequence > r.last) r.last = sequence;
  r.highest = std::max(r.highest, sequence);
  // A robot's own inserts keep their time; a place stored elsewhere does not make it recent.
  if (added) r.last_accepted = start_;
  r.stored.insert(sequence);
}

std::string SequenceGate::Advice(const Robot& robot, int64_t sequence) {
  if (robot.highest < std::numeric_limits<int64_t>::max()) {
    return "continue from " + std::to_string(robot.highest + 1) +
           ", after every sequence the robot has used";
  }
  // A forged frame took the largest sequence: name the next free one after the refused one.
  int64_t candidate = sequence;
  for (auto it = robot.stored.upper_bound(sequence); it != robot.stored.end(); ++it) {
    if (candidate == std::numeric_limits<int64_t>::max()) break;
    if (*it != candidate + 1) break;
    candidate = *it;
  }
  if (candidate == std::numeric_limits<int64_t>::max()) {
    return "no sequence after it is free, choose a lower one that is not stored";
  }
  return "the next free sequence after it is " + std::to_string(candidate + 1);
}

StatusOr<SequenceGate::Admission> SequenceGate::Admit(const std::string& robot, int64_t sequence,
                                                      Clock::time_point now) const {
  std::lock_guard lock(mutex_);
  const auto it = robots_.find(robot);
  if (it == robots_.end()) return Admission::kSameRun;
  const Robot& r = it->second;
  const std::string frame = "sequence " + std::to_string(sequence) + " of robot '" + robot + "'";
  Admission admission = Admission::kSameRun;
  if (sequence <= r.last) {
    const double silent_s = std::chrono::duration<double>(now - r.last_accepted).count();
    if (silent_s < options_.restart_gap_s) {
      char gap[64];
      std::snprintf(gap, sizeof(gap), "%g", options_.restart_gap_s);
      return Status::InvalidArgument(
          frame + " is not after " + std::to_string(r.last) +
          " (frames of a robot must come in order: " + Advice(r, sequence) +
          "; a robot that restarted may also begin again from a lower sequence " + gap +
          " s after its last accepted frame)");
    }
    admission = Admission::kNewRun;
  }
  if (r.stored.count(sequence) > 0) {
    return Status::InvalidArgument(frame +
                                   " is already in the map: a robot's places are named by their "
                                   "sequence, so a restarted robot must not reuse one; " +
                                   Advice(r, sequence));
  }
  return admission;
}

void SequenceGate::Accepted(const std::string& robot, int64_t sequence, bool stored,
                            Clock::time_point now) {
  std::lock_guard lock(mutex_);
  Robot& r = robots_[robot];
  r.last = sequence;
  r.highest = std::max(r.highest, sequence);
  r.last_accepted = now;
  if (stored) r.stored.insert(sequence);
}

int64_t SequenceGate::NextSequence(const std::string& robot) const {
  std::lock_guard lock(mutex_);
  const auto it = robots_.find(robot);
  if (it == robots_.end() || it->second.highest == std::numeric_limits<int64_t>::max()) return -1;
  return it->second.highest + 1;
}

bool SequenceGate::IsStored(const std::string& robot, int64_t sequence) const {
  std::lock_guard lock(mutex_);
  const auto it = robots_.find(robot);
  return it != robots_.end() && it->second.stored.count(sequence) > 0;
}

}  // namespace placerec
