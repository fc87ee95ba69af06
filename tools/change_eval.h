// `placerec-eval change`: scene-change detection (seed §7.2.4) measured with ground truth. A run
// (../shared/data layout) is fed in order; at each true revisit the frame is first asked as a
// query, for half of the revisits with a change made to it (a real object cut from a labelled
// test split pasted in, or a stored landmark painted over with its surroundings), then inserted as
// recorded. Writes OUT/change.json (detection recall by object size, false-alarm rate on the
// unchanged revisits, localisation IoU) and pictures of hits, misses and false alarms; on request
// the changed run itself, for a live check of the alarms through the service (alarm_score.h).
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/eval/paste.h"
#include "common/eval/run.h"
#include "common/pipeline/recognizer.h"
#include "common/util/status.h"

namespace placerec {

struct ChangeEvalOptions {
  std::string out_dir;                       // created; change.json and pictures/
  std::vector<std::string> object_datasets;  // labelled datasets whose test objects are pasted
  CutOptions cut;
  uint64_t seed = 1;             // positions, sizes, objects
  double min_area_share = 0.01;  // pasted objects cover 1 % to 10 % of the frame (log-uniform)
  double max_area_share = 0.10;
  // How far a pasted object's mean colour moves towards the region it covers (PasteObject): 0.5
  // camouflages it halfway, 0 keeps the object's own colours.
  double colour_shift = 0.5;
  // Every this-many changed revisit is a removal (painted over) instead of a paste (0: none).
  int removal_every = 4;
  double min_iou = 0.3;  // a change found with at least this IoU is a hit
  int pictures = 8;      // per kind (hits, misses, false alarms)
  int max_frames = 0;    // stop after this many frames (0: all)
  // When set, the run as the changes left it, to replay through a live server (placerec-client
  // run) while placerec-client watch records the alarms: DIR/runs/<run>_changed.frames.csv and
  // .positives.csv (each changed revisit's frame as changed, in DIR/images; the others as
  // recorded, by absolute path) and DIR/runs/<run>_changed.changes.csv (every revisit: frame,
  // robot, utime_us, case unchanged | pasted | removed, the true box in frame pixels, the frame's
  // size, the pasted object's class). The changed frames are inserted there, not only asked.
  std::string write_run_dir;
  bool progress = true;
};

// Runs the measurement; the JSON is also written to out_dir/change.json.
StatusOr<nlohmann::json> EvaluateChanges(const Run& run, const RecognizerOptions& options,
                                         const ChangeEvalOptions& eval);

}  // namespace placerec
