#include "common/eval/alarms.h"

#include <cstdio>
#include <filesystem>
#include <iterator>
#include <utility>

#include "common/util/csv.h"

namespace placerec {
namespace {

std::string Encode(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '%') {
      out += "%25";
    } else if (c == ',') {
      out += "%2C";
    } else {
      out += c;
    }
  }
  return out;
}

std::string Decode(const std::string& text) {
  std::string out;
  for (size_t i = 0; i < text.size(); ++i) {
    if (text.compare(i, 3, "%25") == 0) {
      out += '%';
      i += 2;
    } else if (text.compare(i, 3, "%2C") == 0) {
      out += ',';
      i += 2;
    } else {
      out += text[i];
    }
  }
  return out;
}

constexpr const char* kColumns[] = {
    "robot", "sequence", "frame_utime", "place_id", "place_robot",  "place_utime", "kind",
    "x",     "y",        "width",       "height",   "object_class", "confidence"};

}  // namespace

std::string WatchedAlarmHeader() {
  std::string header;
  for (const char* column : kColumns) header += (header.empty() ? "" : ",") + std::string(column);
  return header;
}

std::string WatchedAlarmLine(const WatchedAlarm& a) {
  char confidence[32];
  std::snprintf(confidence, sizeof(confidence), "%.3f", a.confidence);
  return Encode(a.robot) + ',' + std::to_string(a.sequence) + ',' + std::to_string(a.frame_utime) +
         ',' + std::to_string(a.place_id) + ',' + Encode(a.place_robot) + ',' +
         std::to_string(a.place_utime) + ',' + (a.appeared ? "appeared" : "disappeared") + ',' +
         std::to_string(a.box.x) + ',' + std::to_string(a.box.y) + ',' +
         std::to_string(a.box.width) + ',' + std::to_string(a.box.height) + ',' +
         Encode(a.object_class) + ',' + confidence;
}

StatusOr<std::vector<WatchedAlarm>> LoadWatchedAlarms(const std::string& path) {
  if (!std::filesystem::exists(path)) {
    return Status::NotFound("no alarms file " + path +
                            " (placerec-client watch --out DIR writes DIR/alarms.csv)");
  }
  StatusOr<CsvTable> table = ReadCsv(path);
  if (!table.ok()) return table.status();
  int col[std::size(kColumns)];
  for (size_t k = 0; k < std::size(kColumns); ++k) {
    col[k] = table->Column(kColumns[k]);
    if (col[k] < 0) {
      return Status::InvalidArgument(path + ": no column '" + kColumns[k] + "'; the header is " +
                                     WatchedAlarmHeader());
    }
  }
  std::vector<WatchedAlarm> alarms;
  for (size_t r = 0; r < table->rows.size(); ++r) {
    const std::vector<std::string>& row = table->rows[r];
    long long n[8];
    const int numeric[8] = {1, 2, 3, 5, 7, 8, 9, 10};
    bool ok = true;
    for (int k = 0; k < 8; ++k) ok = ok && ParseInt64(row[col[numeric[k]]], &n[k]);
    WatchedAlarm a;
    ok = ok && ParseDouble(row[col[12]], &a.confidence);
    const std::string& kind = row[col[6]];
    if (!ok || (kind != "appeared" && kind != "disappeared")) {
      return Status::InvalidArgument(path + ": row " + std::to_string(r + 2) +
                                     ": sequence, times, place, box and confidence must be "
                                     "numbers and kind appeared or disappeared");
    }
    a.robot = Decode(row[col[0]]);
    a.sequence = n[0];
    a.frame_utime = n[1];
    a.place_id = n[2];
    a.place_robot = Decode(row[col[4]]);
    a.place_utime = n[3];
    a.appeared = kind == "appeared";
    a.box = cv::Rect(static_cast<int>(n[4]), static_cast<int>(n[5]), static_cast<int>(n[6]),
                     static_cast<int>(n[7]));
    a.object_class = Decode(row[col[11]]);
    alarms.push_back(std::move(a));
  }
  return alarms;
}

}  // namespace placerec
