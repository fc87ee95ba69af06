#include "tools/alarm_score.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <map>
#include <set>
#include <utility>

#include "common/eval/paste.h"
#include "common/util/csv.h"
#include "tools/change_tally.h"

namespace placerec {
namespace {

// The columns `names` of `table`, or InvalidArgument naming the first missing one.
Status FindColumns(const CsvTable& table, const std::string& path,
                   const std::vector<std::string>& names, std::vector<int>* columns) {
  columns->clear();
  for (const std::string& name : names) {
    const int c = table.Column(name);
    if (c < 0) return Status::InvalidArgument(path + ": no column '" + name + "'");
    columns->push_back(c);
  }
  return Status::Ok();
}

// Parses the integer fields `fields[columns[k]]` into `values[k]`.
bool ParseInts(const std::vector<std::string>& fields, const std::vector<int>& columns,
               std::vector<long long>* values) {
  values->assign(columns.size(), 0);
  for (size_t k = 0; k < columns.size(); ++k) {
    if (!ParseInt64(fields[columns[k]], &(*values)[k])) return false;
  }
  return true;
}

}  // namespace

StatusOr<std::vector<ChangeCase>> LoadChangeCases(const std::string& path) {
  if (!std::filesystem::exists(path)) {
    return Status::NotFound("no changes file " + path +
                            " (placerec-eval change --write-run DIR writes "
                            "DIR/runs/NAME_changed.changes.csv)");
  }
  StatusOr<CsvTable> table = ReadCsv(path);
  if (!table.ok()) return table.status();
  std::vector<int> col;
  PLACEREC_RETURN_IF_ERROR(FindColumns(*table, path,
                                       {"frame", "robot", "utime_us", "case", "x", "y", "width",
                                        "height", "frame_width", "frame_height", "object_class"},
                                       &col));
  const std::vector<int> numbers = {col[0], col[2], col[4], col[5], col[6], col[7], col[8], col[9]};
  std::vector<ChangeCase> cases;
  for (size_t r = 0; r < table->rows.size(); ++r) {
    const std::vector<std::string>& row = table->rows[r];
    const std::string where = path + ": row " + std::to_string(r + 2);
    std::vector<long long> v;
    if (!ParseInts(row, numbers, &v)) {
      return Status::InvalidArgument(where +
                                     ": frame, utime_us, box and frame size must be "
                                     "integers");
    }
    ChangeCase c;
    c.frame = static_cast<int>(v[0]);
    c.robot = row[col[1]];
    c.utime = v[1];
    const std::string& kind = row[col[3]];
    if (kind == "unchanged") {
      c.kind = ChangeCase::Kind::kUnchanged;
    } else if (kind == "pasted") {
      c.kind = ChangeCase::Kind::kPasted;
    } else if (kind == "removed") {
      c.kind = ChangeCase::Kind::kRemoved;
    } else {
      return Status::InvalidArgument(where + ": case '" + kind +
                                     "' is none of unchanged, pasted, removed");
    }
    c.truth = cv::Rect(static_cast<int>(v[2]), static_cast<int>(v[3]), static_cast<int>(v[4]),
                       static_cast<int>(v[5]));
    c.frame_size = cv::Size(static_cast<int>(v[6]), static_cast<int>(v[7]));
    c.object_class = row[col[10]];
    if (c.kind != ChangeCase::Kind::kUnchanged && (c.truth.empty() || c.frame_size.area() <= 0)) {
      return Status::InvalidArgument(where + ": a changed revisit needs its box and frame size");
    }
    cases.push_back(std::move(c));
  }
  return cases;
}

nlohmann::json ScoreAlarms(const std::vector<ChangeCase>& cases,
                           const std::vector<WatchedAlarm>& alarms, double min_iou) {
  // The alarms of each frame: (robot, sequence), the sequence being the run's frame index.
  std::map<std::pair<std::string, int64_t>, std::vector<const WatchedAlarm*>> by_frame;
  for (const WatchedAlarm& a : alarms) by_frame[{a.robot, a.sequence}].push_back(&a);
  ChangeTally pasted, removed;
  int unchanged = 0, false_alarms = 0;
  std::set<std::pair<std::string, int64_t>> revisits;
  for (const ChangeCase& c : cases) {
    const std::pair<std::string, int64_t> key{c.robot, c.frame};
    revisits.insert(key);
    const auto found = by_frame.find(key);
    const std::vector<const WatchedAlarm*> none;
    const std::vector<const WatchedAlarm*>& raised = found == by_frame.end() ? none : found->second;
    if (c.kind == ChangeCase::Kind::kUnchanged) {
      ++unchanged;
      false_alarms += raised.empty() ? 0 : 1;
      continue;
    }
    double best = 0;
    for (const WatchedAlarm* a : raised) best = std::max(best, BoxIoU(a->box, c.truth));
    ChangeTally& tally = c.kind == ChangeCase::Kind::kPasted ? pasted : removed;
    tally.Add(static_cast<double>(c.truth.area()) / c.frame_size.area(), best >= min_iou, best);
  }
  int elsewhere = 0;
  for (const auto& [key, raised] : by_frame) elsewhere += revisits.count(key) == 0 ? 1 : 0;

  nlohmann::json j;
  j["appeared"] = ChangeTallyJson(pasted);
  j["removed"] = ChangeTallyJson(removed);
  // Whether a frame was compared is in the answer, not in the alarms.
  j["appeared"].erase("compared");
  j["removed"].erase("compared");
  j["detection_recall"] = j["appeared"]["detection_recall"];
  j["detection_recall_2pct"] = j["appeared"]["detection_recall_2pct"];
  j["localisation_iou"] = j["appeared"]["localisation_iou_median"];
  j["revisits"] = cases.size();
  j["unchanged"] = unchanged;
  j["false_alarms"] = false_alarms;
  j["false_alarm_rate"] = ShareOf(false_alarms, unchanged);
  j["alarms"] = alarms.size();
  j["frames_alarmed_elsewhere"] = elsewhere;
  j["min_iou"] = min_iou;
  return j;
}

}  // namespace placerec
