// The alarms file of `placerec-client watch --out W` (W/alarms.csv): one line per scene-change
// alarm (seed §7.2.4) as it arrived on PLACEREC_CHANGE, so that alarms watched live can be
// scored (tools/alarm_score.h) or looked at in a spreadsheet.
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
  int64_t place_id = -1;  // the stored place, the robot that stored it and its capture time
  std::string place_robot;
  int64_t place_utime = 0;
  bool appeared = true;  // false: disappeared
  cv::Rect box;          // pixels of the frame as sent
  std::string object_class;
  double confidence = 0;
};

// The header of W/alarms.csv, and one alarm as its line (without the newline). Robot ids and
// classes are written with '%' and ',' percent-encoded (the CSV has no quoting).
std::string WatchedAlarmHeader();
std::string WatchedAlarmLine(const WatchedAlarm& alarm);

// Reads W/alarms.csv: NotFound when missing, InvalidArgument naming the row for a malformed line.
StatusOr<std::vector<WatchedAlarm>> LoadWatchedAlarms(const std::string& path);

}  // namespace placerec
