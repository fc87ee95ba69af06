// Feeds a run (../shared/data layout) through the recognition pipeline in-process and writes
// what placerec-eval promises: answers.csv, candidates.csv, summary.json, pr_curve.png and match
// pictures.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/eval/answers.h"
#include "common/eval/run.h"
#include "common/eval/scoring.h"
#include "common/pipeline/recognizer.h"
#include "common/util/status.h"

namespace placerec {

struct EvalOptions {
  std::string out_dir;               // created if missing; empty writes nothing
  std::string db_path;               // SQLite map; empty keeps the map in memory
  int pictures = 6;                  // match pictures to draw (best true and false positives)
  bool progress = true;              // a progress line on stderr
  bool print_loop_closures = false;  // one stdout line per loop closure as it is found
  // Frames fed: [first_frame, max_frames), max_frames 0 meaning the run's end. A first frame
  // above 0 continues a map (db_path) that an earlier call built from the frames before it, as a
  // restarted server would; only the revisits among the fed frames are scored.
  int first_frame = 0;
  int max_frames = 0;  // stop before this frame (0: all); with first_frame 0, a frame count
  // Every frame is scaled to this width as it is read (0: as recorded), as a camera of that
  // resolution would send it; the pipeline's own scaling comes after.
  int frame_width = 0;
};

struct EvalReport {
  std::vector<Answer> answers;
  RunScore score;
  nlohmann::json summary;  // what summary.json holds
};

StatusOr<EvalReport> EvaluateRun(const Run& run, const RecognizerOptions& options,
                                 const EvalOptions& eval);

}  // namespace placerec
