// The files of the live check of scene-change alarms (seed §7.2.4): the alarms file of
// `placerec-client watch --out W` (W/alarms.csv: one line per alarm as it arrived on
// PLACEREC_CHANGE, also for a spreadsheet) and the changes file of a run changed by
// `placerec-eval change --write-run` (the truth they are scored against, tools/alarm_score.h).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "common/util/status.h"

namespace placerec {

struct WatchedAlarm {
  std::string robot;
  int64_t sequence = 0;
  int64_t frame_utime = 0;
  // The stored place compared with: its id, the robot that stored it and its capture time.
  int64_t place_id = -1;
  std::string place_robot;
  int64_t place_utime = 0;
  bool appeared = true;  // false: disappeared
  cv::Rect box;          // pixels of the frame as sent
  cv::Size frame_size;   // the frame as sent, pixels
  std::string object_class;
  double confidence = 0;
};

// The header of W/alarms.csv, and one alarm as its line (without the newline). Robot ids and
// classes are written with '%' and ',' percent-encoded (the CSV has no quoting).
std::string WatchedAlarmHeader();
std::string WatchedAlarmLine(const WatchedAlarm& alarm);

// Reads W/alarms.csv: NotFound when missing, InvalidArgument naming the file and line for a
// malformed one. Numbers are written and read locale-independently.
StatusOr<std::vector<WatchedAlarm>> LoadWatchedAlarms(const std::string& path);

// One revisit of a changed run (DIR/runs/<run>_changed.changes.csv).
struct ChangeCase {
  // kNotMade: a change was planned for this revisit but could not be made (the object did not
  // fit the frame, no landmark to paint over): the frame is sent unchanged, and counts neither
  // as a change nor as an unchanged revisit (such frames are mostly ones matched poorly, which
  // would make the false-alarm rate look lower).
  enum class Kind { kUnchanged, kPasted, kRemoved, kNotMade };
  int frame = 0;  // the run's frame index: the sequence number placerec-client run sends
  std::string robot;
  int64_t utime = 0;
  Kind kind = Kind::kUnchanged;
  cv::Rect truth;            // frame pixels; empty for an unchanged revisit
  cv::Size frame_size;       // pixels
  std::string object_class;  // of a pasted object
  // Share of the frame the change covers: a pasted object's mask (its box covers more), a
  // painted box; what the size bands of recall count. 0: not recorded (a file of an older
  // placerec: the box's share is taken).
  double area_share = 0;
  double AreaShare() const {
    if (area_share > 0) return area_share;
    return frame_size.area() > 0 ? static_cast<double>(truth.area()) / frame_size.area() : 0;
  }
};

// "unchanged", "pasted", "removed", "not_made": the case column of a changes file.
const char* ChangeCaseKindName(ChangeCase::Kind kind);

// The header of a changes file, and one revisit as its line (without the newline).
std::string ChangeCaseHeader();
std::string ChangeCaseLine(const ChangeCase& change);

// Reads a changes file: NotFound when missing, InvalidArgument naming the file and line for a
// malformed one.
StatusOr<std::vector<ChangeCase>> LoadChangeCases(const std::string& path);

}  // namespace placerec
