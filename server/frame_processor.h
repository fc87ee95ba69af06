// Answers one frame message (DESIGN.md "LCM protocol"): checks the request (including the
// sequence rule of server/sequence_gate.h), decodes the image and runs the recognizer, whose map
// commits the frame's landmarks before it returns, then builds the answer. Every failure becomes
// an error answer that says what was wrong; nothing throws.
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

#include "common/image/image.h"
#include "common/pipeline/place_map.h"
#include "common/pipeline/recognizer.h"
#include "placerec/change_t.hpp"
#include "placerec/frame_t.hpp"
#include "placerec/result_t.hpp"
#include "server/sequence_gate.h"

namespace placerec {

class FrameProcessor {
 public:
  // `map` must outlive the processor; a null `segmenter` or `labeler` is made from the options.
  // The sequence rule learns the robots' stored places from `map`.
  FrameProcessor(const RecognizerOptions& options, const DecodeOptions& decode, PlaceMap* map,
                 std::unique_ptr<Segmenter> segmenter = nullptr,
                 const SequenceRuleOptions& sequence_rule = SequenceRuleOptions(),
                 std::shared_ptr<const ObjectClassLabeler> labeler = nullptr);

  // Frames of one robot must come one at a time and in order; frames of different robots may be
  // processed from different threads at once (Recognizer's contract).
  // `alarms` (may be null) receives the frame's scene-change alarms (protocol.h AlarmMessages).
  result_t Process(const frame_t& frame, std::vector<change_t>* alarms = nullptr);

  PlaceMap& map() { return *map_; }

  // A place another server stored in the shared map: the sequence rule learns it as it learns the
  // places loaded at start. Thread-safe.
  void NoteStored(const Place& place) { gate_.AddStored(place.robot, place.sequence); }

  // The robots whose run the processor keeps (at most SequenceRuleOptions::max_robot_runs),
  // in no particular order. Thread-safe.
  std::vector<std::string> RobotsWithRuns() const;

 private:
  result_t ProcessOrThrow(const frame_t& frame, std::vector<change_t>* alarms);
  // A recognizer for one run of a robot: its own short-term memory, the shared segmenter.
  std::unique_ptr<Recognizer> NewRun() const;
  // The robot's current run (null when it has none), marked as the most recently used.
  std::shared_ptr<Recognizer> FindRun(const std::string& robot);
  // Makes `run` the robot's current run; forgets the least recently used other run when more
  // than max_robot_runs robots have one.
  void KeepRun(const std::string& robot, std::shared_ptr<Recognizer> run);

  RecognizerOptions options_;
  DecodeOptions decode_;
  PlaceMap* map_;
  // Analyzes every frame (stateless) and owns the segmenter the runs share.
  Recognizer analyzer_;
  SequenceGate gate_;
  const int max_runs_;
  struct Run {
    // Shared with the frame that uses it, so that forgetting a run (another robot's frame may)
    // never pulls it from under a frame in progress.
    std::shared_ptr<Recognizer> recognizer;
    uint64_t last_used = 0;  // runs_clock_ when the robot's last frame looked it up
  };
  mutable std::mutex runs_mutex_;
  uint64_t runs_clock_ = 0;
  // Each robot's current run. A robot's entry is only replaced from its own frames, which come
  // one at a time.
  std::unordered_map<std::string, Run> runs_;
};

}  // namespace placerec
