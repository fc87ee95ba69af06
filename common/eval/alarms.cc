#include "common/eval/alarms.h"

#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <utility>

#include "common/eval/csv_lines.h"

namespace placerec {
namespace {

using eval_internal::CsvLines;
using eval_internal::FormatDouble;
using eval_internal::ParseFloat;
using eval_internal::ParseInt;

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

enum Column {
  kRobot,
  kSequence,
  kFrameUtime,
  kPlaceId,
  kPlaceRobot,
  kPlaceUtime,
  kKind,
  kX,
  kY,
  kWidth,
  kHeight,
  kFrameWidth,
  kFrameHeight,
  kObjectClass,
  kConfidence,
  kColumns
};
constexpr const char* kColumnNames[kColumns] = {"robot",
                                                "sequence",
                                                "frame_utime",
                                                "place_id",
                                                "place_robot",
                                                "place_utime",
                                                "kind",
                                                "x",
                                                "y",
                                                "width",
                                                "height",
                                                "frame_width",
                                                "frame_height",
                                                "object_class",
                                                "confidence"};

}  // namespace

std::string WatchedAlarmHeader() {
  std::string header;
  for (const char* column : kColumnNames) {
    header += (header.empty() ? "" : ",") + std::string(column);
  }
  return header;
}

std::string WatchedAlarmLine(const WatchedAlarm& a) {
  return Encode(a.robot) + ',' + std::to_string(a.sequence) + ',' + std::to_string(a.frame_utime) +
         ',' + std::to_string(a.place_id) + ',' + Encode(a.place_robot) + ',' +
         std::to_string(a.place_utime) + ',' + (a.appeared ? "appeared" : "disappeared") + ',' +
         std::to_string(a.box.x) + ',' + std::to_string(a.box.y) + ',' +
         std::to_string(a.box.width) + ',' + std::to_string(a.box.height) + ',' +
         std::to_string(a.frame_size.width) + ',' + std::to_string(a.frame_size.height) + ',' +
         Encode(a.object_class) + ',' + FormatDouble(a.confidence);
}

StatusOr<std::vector<WatchedAlarm>> LoadWatchedAlarms(const std::string& path) {
  StatusOr<CsvLines> table = eval_internal::ReadCsvLines(path);
  if (!table.ok()) {
    if (table.status().code() != StatusCode::kNotFound) return table.status();
    return Status::NotFound(table.status().message() +
                            " (placerec-client watch --out DIR writes DIR/alarms.csv)");
  }
  int col[kColumns];
  for (int k = 0; k < kColumns; ++k) {
    col[k] = table->Column(kColumnNames[k]);
    if (col[k] < 0) {
      return Status::InvalidArgument(path + ": no column '" + kColumnNames[k] +
                                     "'; the header is " + WatchedAlarmHeader());
    }
  }
  std::vector<WatchedAlarm> alarms;
  for (const eval_internal::CsvLine& row : table->rows) {
    const auto field = [&](Column c) -> const std::string& { return row.fields[col[c]]; };
    long long n[kColumns] = {};
    bool ok = true;
    for (Column c : {kSequence, kFrameUtime, kPlaceId, kPlaceUtime, kX, kY, kWidth, kHeight,
                     kFrameWidth, kFrameHeight}) {
      ok = ok && ParseInt(field(c), &n[c]);
    }
    WatchedAlarm a;
    ok = ok && ParseFloat(field(kConfidence), &a.confidence);
    const std::string& kind = field(kKind);
    if (!ok || (kind != "appeared" && kind != "disappeared")) {
      return Status::InvalidArgument(table->Where(row.line) +
                                     ": sequence, times, place, box, frame size and confidence "
                                     "must be numbers and kind appeared or disappeared");
    }
    a.robot = Decode(field(kRobot));
    a.sequence = n[kSequence];
    a.frame_utime = n[kFrameUtime];
    a.place_id = n[kPlaceId];
    a.place_robot = Decode(field(kPlaceRobot));
    a.place_utime = n[kPlaceUtime];
    a.appeared = kind == "appeared";
    a.box = cv::Rect(static_cast<int>(n[kX]), static_cast<int>(n[kY]), static_cast<int>(n[kWidth]),
                     static_cast<int>(n[kHeight]));
    a.frame_size = cv::Size(static_cast<int>(n[kFrameWidth]), static_cast<int>(n[kFrameHeight]));
    a.object_class = Decode(field(kObjectClass));
    alarms.push_back(std::move(a));
  }
  return alarms;
}

namespace {

enum ChangeColumn {
  kCaseFrame,
  kCaseRobot,
  kCaseUtime,
  kCaseKind,
  kCaseX,
  kCaseY,
  kCaseWidth,
  kCaseHeight,
  kCaseFrameWidth,
  kCaseFrameHeight,
  kCaseObjectClass,
  kCaseAreaShare,  // optional: files of older placerec lack it
  kCaseColumns
};
constexpr const char* kCaseColumnNames[kCaseColumns] = {
    "frame",  "robot",       "utime_us",     "case",         "x",         "y", "width",
    "height", "frame_width", "frame_height", "object_class", "area_share"};
constexpr ChangeCase::Kind kCaseKinds[] = {ChangeCase::Kind::kUnchanged, ChangeCase::Kind::kPasted,
                                           ChangeCase::Kind::kRemoved, ChangeCase::Kind::kNotMade};

}  // namespace

// A share of the frame in a changes file: six significant digits.
static std::string ShareText(double share) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.6g", share);
  return text;
}

const char* ChangeCaseKindName(ChangeCase::Kind kind) {
  switch (kind) {
    case ChangeCase::Kind::kUnchanged:
      return "unchanged";
    case ChangeCase::Kind::kPasted:
      return "pasted";
    case ChangeCase::Kind::kRemoved:
      return "removed";
    case ChangeCase::Kind::kNotMade:
      return "not_made";
  }
  return "?";
}

std::string ChangeCaseHeader() {
  std::string header;
  for (const char* column : kCaseColumnNames) {
    header += (header.empty() ? "" : ",") + std::string(column);
  }
  return header;
}

std::string ChangeCaseLine(const ChangeCase& c) {
  return std::to_string(c.frame) + ',' + Encode(c.robot) + ',' + std::to_string(c.utime) + ',' +
         ChangeCaseKindName(c.kind) + ',' + std::to_string(c.truth.x) + ',' +
         std::to_string(c.truth.y) + ',' + std::to_string(c.truth.width) + ',' +
         std::to_string(c.truth.height) + ',' + std::to_string(c.frame_size.width) + ',' +
         std::to_string(c.frame_size.height) + ',' + Encode(c.object_class) + ',' +
         ShareText(c.area_share);
}

StatusOr<std::vector<ChangeCase>> LoadChangeCases(const std::string& path) {
  StatusOr<CsvLines> table = eval_internal::ReadCsvLines(path);
  if (!table.ok()) {
    if (table.status().code() != StatusCode::kNotFound) return table.status();
    return Status::NotFound(table.status().message() +
                            " (placerec-eval change --write-run DIR writes "
                            "DIR/runs/NAME_changed.changes.csv)");
  }
  int col[kCaseColumns];
  for (int k = 0; k < kCaseColumns; ++k) {
    col[k] = table->Column(kCaseColumnNames[k]);
    if (col[k] < 0 && k != kCaseAreaShare) {
      return Status::InvalidArgument(path + ": no column '" + kCaseColumnNames[k] +
                                     "'; the header is " + ChangeCaseHeader());
    }
  }
  std::vector<ChangeCase> cases;
  for (const eval_internal::CsvLine& row : table->rows) {
    const auto field = [&](ChangeColumn c) -> const std::string& { return row.fields[col[c]]; };
    long long n[kCaseColumns] = {};
    bool ok = true;
    for (ChangeColumn c : {kCaseFrame, kCaseUtime, kCaseX, kCaseY, kCaseWidth, kCaseHeight,
                           kCaseFrameWidth, kCaseFrameHeight}) {
      ok = ok && ParseInt(field(c), &n[c]);
    }
    if (!ok) {
      return Status::InvalidArgument(table->Where(row.line) +
                                     ": frame, utime_us, box and frame size must be integers");
    }
    ChangeCase c;
    c.frame = static_cast<int>(n[kCaseFrame]);
    c.robot = Decode(field(kCaseRobot));
    c.utime = n[kCaseUtime];
    bool known = false;
    for (ChangeCase::Kind kind : kCaseKinds) {
      if (field(kCaseKind) == ChangeCaseKindName(kind)) {
        c.kind = kind;
        known = true;
      }
    }
    if (!known) {
      return Status::InvalidArgument(table->Where(row.line) + ": case '" + field(kCaseKind) +
                                     "' is none of unchanged, pasted, removed, not_made");
    }
    c.truth = cv::Rect(static_cast<int>(n[kCaseX]), static_cast<int>(n[kCaseY]),
                       static_cast<int>(n[kCaseWidth]), static_cast<int>(n[kCaseHeight]));
    c.frame_size =
        cv::Size(static_cast<int>(n[kCaseFrameWidth]), static_cast<int>(n[kCaseFrameHeight]));
    c.object_class = Decode(field(kCaseObjectClass));
    if (col[kCaseAreaShare] >= 0 && !field(kCaseAreaShare).empty()) {
      char* end = nullptr;
      const std::string& text = field(kCaseAreaShare);
      c.area_share = std::strtod(text.c_str(), &end);
      if (end != text.c_str() + text.size() || !(c.area_share >= 0 && c.area_share <= 1)) {
        return Status::InvalidArgument(table->Where(row.line) + ": area_share '" + text +
                                       "' is not a share of the frame in [0, 1]");
      }
    }
    const bool changed =
        c.kind == ChangeCase::Kind::kPasted || c.kind == ChangeCase::Kind::kRemoved;
    if (changed && (c.truth.empty() || c.frame_size.area() <= 0)) {
      return Status::InvalidArgument(table->Where(row.line) +
                                     ": a changed revisit needs its box and frame size");
    }
    cases.push_back(std::move(c));
  }
  return cases;
}

}  // namespace placerec
