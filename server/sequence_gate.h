// The sequence rule for inserted frames (issue 23 item 3), kept by the server so that neither a
// forged frame nor a robot's own restart locks the robot out, and so that the rule survives a
// server restart:
//
// - A place is named by its robot and sequence (the map stores each pair once), so an insert
//   whose sequence is already stored for its robot is refused, and the answer names the sequence
//   to continue from: the one after every sequence the robot has used, so that a robot that
//   follows it numbers its frames after its earlier runs instead of into their gaps.
// - Within a run of the robot, sequences increase: an insert whose sequence is not after the
//   robot's last accepted one is refused (a late or repeated datagram) ...
// - ... unless the robot's last accepted insert is at least `restart_gap_s` old (server clock):
//   then the frame begins a new run of the robot (it restarted, or a forged frame took a sequence
//   far ahead) and the robot's short-term memory starts afresh.
// At start the gate learns every stored place from the map: each robot's last sequence is its
// largest stored one, accepted "at start-up".
#pragma once

#include <chrono>
#include <cstdint>
#include <limits>
#include <mutex>
#include <set>
#include <string>
#include <unordered_map>

#include "common/util/status.h"

namespace placerec {

struct SequenceRuleOptions {
  // Seconds after a robot's last accepted insert from which a lower sequence begins a new run
  // of the robot instead of being refused as out of order.
  double restart_gap_s = 5.0;
  // Robots whose run (short-term memory: the recent past that keeps a robot's own places from
  // answering it, the frames its landmarks are tracked in) the server keeps at most; beyond it
  // the run of the robot silent longest is forgotten, and that robot's next frame begins a new
  // run (its size: docs/results.md). A site's robots are far fewer, so only a server that sees
  // ever new robot ids (ids made per boot, forged ids) reaches it.
  int max_robot_runs = 1000;

  bool Check(std::string* error) const;
};

class SequenceGate {
 public:
  using Clock = std::chrono::steady_clock;

  // What an admitted insert is.
  enum class Admission {
    kSameRun,  // after the robot's last sequence (or the robot's first insert)
    kNewRun,   // not after it, but the robot was silent long enough: a restart
  };

  explicit SequenceGate(const SequenceRuleOptions& options, Clock::time_point start = Clock::now())
      : options_(options), start_(start) {}

  // A place the map holds (loaded at start, or stored since by another server on a shared map):
  // raises the robot's last sequence to it. A robot first seen this way counts as last accepted
  // at start-up; a known robot keeps the time of its last accepted insert.
  void AddStored(const std::string& robot, int64_t sequence);

  // Whether an insert of `robot` with `sequence` arriving at `now` may go ahead; an
  // InvalidArgument error saying why and what to send instead otherwise. Changes nothing.
  StatusOr<Admission> Admit(const std::string& robot, int64_t sequence,
                            Clock::time_point now) const;

  // An admitted insert succeeded at `now`; `stored` when it added a place to the map (a frame
  // that showed nothing new is answered without one).
  void Accepted(const std::string& robot, int64_t sequence, bool stored, Clock::time_point now);

  // Whether the map holds a place of `robot` with `sequence` (as far as this gate learned).
  bool IsStored(const std::string& robot, int64_t sequence) const;

  // The sequence `robot`'s next insert should carry at least: after every sequence the robot has
  // used (stored or accepted); -1 for a robot this gate knows no sequence of, or whose largest
  // sequence is the largest there is.
  int64_t NextSequence(const std::string& robot) const;

 private:
  struct Robot {
    int64_t last = 0;  // the last accepted sequence (of the robot's current run)
    int64_t highest = std::numeric_limits<int64_t>::min();  // of every run, stored or accepted
    Clock::time_point last_accepted;
    std::set<int64_t> stored;
  };
  // What a refused robot should send instead: the sequence after every one it has used, or, when
  // there is none (a forged frame took the largest), a lower one that is not stored.
  static std::string Advice(const Robot& robot, int64_t sequence);

  const SequenceRuleOptions options_;
  const Clock::time_point start_;
  mutable std::mutex mutex_;
  std::unordered_map<std::string, Robot> robots_;
};

}  // namespace placerec
