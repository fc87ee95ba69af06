#include "tools/alarm_score.h"

#include <algorithm>
#include <map>
#include <set>
#include <utility>

#include "common/eval/paste.h"
#include "tools/change_tally.h"

namespace placerec {

nlohmann::json ScoreAlarms(const std::vector<ChangeCase>& cases,
                           const std::vector<WatchedAlarm>& alarms, double min_iou) {
  // The alarms of each frame: (robot, sequence), the sequence being the run's frame index.
  std::map<std::pair<std::string, int64_t>, std::vector<const WatchedAlarm*>> by_frame;
  for (const WatchedAlarm& a : alarms) by_frame[{a.robot, a.sequence}].push_back(&a);
  ChangeTally pasted, removed;
  int unchanged = 0, false_alarms = 0, not_made = 0;
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
    if (c.kind == ChangeCase::Kind::kNotMade) {
      ++not_made;
      continue;
    }
    double best = 0;
    for (const WatchedAlarm* a : raised) {
      cv::Rect box = a->box;
      if (a->frame_size.width > 0 && a->frame_size != c.frame_size) {
        // The frame was sent at another size: its box in the case's pixels.
        const double s = static_cast<double>(c.frame_size.width) / a->frame_size.width;
        box = cv::Rect(cv::Point(cvRound(box.x * s), cvRound(box.y * s)),
                       cv::Point(cvRound(box.br().x * s), cvRound(box.br().y * s)));
      }
      best = std::max(best, BoxIoU(box, c.truth));
    }
    ChangeTally& tally = c.kind == ChangeCase::Kind::kPasted ? pasted : removed;
    tally.Add(c.AreaShare(), best >= min_iou, best);
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
  j["changes_not_made"] = not_made;
  j["alarms"] = alarms.size();
  j["frames_alarmed_elsewhere"] = elsewhere;
  j["min_iou"] = min_iou;
  return j;
}

}  // namespace placerec
