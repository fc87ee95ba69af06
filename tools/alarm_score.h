// `placerec-eval alarms`: the live check of scene-change alarms (seed §7.2.4). A run changed by
// `placerec-eval change --write-run DIR` is replayed through a running server
// (`placerec-client run`) while `placerec-client watch --out W` records every alarm in
// W/alarms.csv; the alarms are then scored against the run's changes as `placerec-eval change`
// scores the detector's answers offline: pasted objects found with IoU >= 0.3 (by size band),
// unchanged revisits with any alarm, the median IoU of the hits. scripts/watch-changes.sh does
// all of it.
#pragma once

#include <vector>

#include <nlohmann/json.hpp>

#include "common/eval/alarms.h"

namespace placerec {

// The scores (keys as in change.json where they mean the same): appeared / removed tallies,
// detection_recall, detection_recall_2pct, localisation_iou, unchanged, false_alarms,
// false_alarm_rate, alarms, and frames_alarmed_elsewhere (frames that are no revisit of the
// cases file, e.g. a first pass matched to another place, with an alarm).
// An alarm's box is scaled to the case's frame size when the frame was sent at another size.
nlohmann::json ScoreAlarms(const std::vector<ChangeCase>& cases,
                           const std::vector<WatchedAlarm>& alarms, double min_iou);

}  // namespace placerec
