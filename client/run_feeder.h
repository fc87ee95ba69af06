// Feeds a place-recognition run (layout of ../shared/data/README.md) through a placerec-server:
// each frame goes out as its robot with sequence = the run's frame index and the run's capture
// time, exactly as placerec-eval feeds the pipeline in-process, so that the answers.csv written
// from the answers (best match's sequence and score, -1 when there is none) equals placerec-eval's.
#pragma once

#include <atomic>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "client/client.h"
#include "common/eval/answers.h"
#include "common/eval/run.h"
#include "common/eval/scoring.h"
#include "common/util/status.h"

namespace placerec {

struct FeedOptions {
  // Frames in flight at once (per robot with robots_concurrently). 1 sends a frame only after the
  // previous one is answered, which reproduces placerec-eval's answers on any run; more pipelines
  // the frames (still exact for one-robot runs, since the server keeps each robot's order).
  int window = 1;
  // One sender per robot, all at once (throughput tests). Robots then see each other's places
  // as soon as the server stores them, so the answers depend on timing.
  bool robots_concurrently = false;
  int max_frames = 0;               // stop after this many frames (0: all)
  double timeout_s = 60;            // per frame, from its publication
  bool print_loop_closures = true;  // one stdout line per loop closure as it arrives
  bool progress = true;             // a progress line on stderr
  // When set (Ctrl-C): no further frame is sent, the frames in flight are awaited, and the
  // report covers what was sent ("interrupted" in summary.json; the rest count as not sent).
  const std::atomic<bool>* stop = nullptr;

  bool Check(std::string* error) const;
};

struct FeedReport {
  std::vector<FrameResult> results;  // per fed frame, in frame order
  std::vector<Answer> answers;       // answers.csv rows, in frame order
  RunScore score;
  nlohmann::json summary;  // what summary.json holds
  int ok = 0;              // answers with status ok
  int failed = 0;          // answers with an error status
  int timed_out = 0;       // frames without an answer in time
  int not_sent = 0;        // frames never published (after a timeout, or LCM refused them)
  bool all_ok() const { return failed == 0 && timed_out == 0 && not_sent == 0; }
};

// Feeds `run` and scores the answers. An error only for bad options or an unreadable image; a
// frame without an answer stops that sender (the server is likely gone) and is counted.
StatusOr<FeedReport> FeedRun(PlacerecClient* client, const Run& run, const FeedOptions& options);

// Writes OUT/answers.csv, OUT/summary.json and OUT/pr_curve.png (creating OUT).
Status WriteFeedReport(const std::string& out_dir, const FeedReport& report);

}  // namespace placerec
