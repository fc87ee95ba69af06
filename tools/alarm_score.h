// `placerec-eval alarms`: the live check of scene-change alarms (seed §7.2.4). A run changed by
// `placerec-eval change --write-run DIR` is replayed through a running server
// (`placerec-client run`) while `placerec-client watch --out W` records every alarm in
// W/alarms.csv; the alarms are then scored against the run's changes as `placerec-eval change`
// scores the detector's answers offline: pasted objects found with IoU >= 0.3 (by size band),
// unchanged revisits with any alarm, the median IoU of the hits. scripts/watch-changes.sh does
// all of it.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "common/eval/alarms.h"
#include "common/util/status.h"

namespace placerec {

// One revisit of a changed run (DIR/runs/<run>_changed.changes.csv).
struct ChangeCase {
  enum class Kind { kUnchanged, kPasted, kRemoved };
  int frame = 0;  // the run's frame index: the sequence number placerec-client run sends
  std::string robot;
  int64_t utime = 0;
  Kind kind = Kind::kUnchanged;
  cv::Rect truth;            // frame pixels; empty for an unchanged revisit
  cv::Size frame_size;       // pixels
  std::string object_class;  // of a pasted object
};

// Reads a changes file; InvalidArgument naming the row for a malformed line, NotFound when
// missing.
StatusOr<std::vector<ChangeCase>> LoadChangeCases(const std::string& path);

// The scores (keys as in change.json where they mean the same): appeared / removed tallies,
// detection_recall, detection_recall_2pct, localisation_iou, unchanged, false_alarms,
// false_alarm_rate, alarms, and frames_alarmed_elsewhere (frames that are no revisit of the
// cases file, e.g. a first pass matched to another place, with an alarm).
nlohmann::json ScoreAlarms(const std::vector<ChangeCase>& cases,
                           const std::vector<WatchedAlarm>& alarms, double min_iou);

}  // namespace placerec
