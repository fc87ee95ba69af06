// Place-recognition runs in the layout of ../shared/data/README.md:
//   <dataset>/runs/<run>.frames.csv     frame,robot,image,utime_us
//   <dataset>/runs/<run>.positives.csv  query,reference
#pragma once

#include <cstdint>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "common/util/status.h"

namespace placerec {

struct RunFrame {
  int frame = 0;  // counts from 0 in feeding order
  std::string robot;
  std::string image;  // absolute or dataset-relative path joined with the dataset directory
  int64_t utime = 0;  // capture time, microseconds since the epoch
};

// A loaded run. (Inside a GoogleTest body write placerec::Run: testing::Test::Run() hides it.)
struct Run {
  std::string dataset_dir;
  std::string name;
  std::vector<RunFrame> frames;
  std::set<std::pair<int, int>> positives;  // (query, reference), reference < query
  std::vector<bool> is_revisit;             // per frame: has at least one positive
  int num_revisits = 0;

  bool IsPositive(int query, int reference) const {
    return positives.count({query, reference}) > 0;
  }
};

// Loads a run and checks it: the header columns, frames numbered 0..n-1 in file order (at least
// one), non-empty robot and image, utime monotonic non-decreasing per robot, positives referring
// to existing frames with reference < query. Fills is_revisit and num_revisits. NotFound (listing
// the available runs) when the run or its positives file is missing; InvalidArgument naming the
// file and line, and what to fix, for malformed content. Numbers are parsed locale-independently.
StatusOr<Run> LoadRun(const std::string& dataset_dir, const std::string& run_name);

// The run cut to its first `frames` frames (positives, revisit flags and count with it), for
// scoring a partial feed. The whole run when `frames` is not below its length.
Run FirstFrames(const Run& run, int frames);

// The run as a faster camera would send it: every frame `copies` times, `interval_us` apart in
// capture time (a robot standing still for a moment, or a camera at 1e6 / interval_us frames per
// second). A robot's next frame keeps its capture time unless the copies reach it; then the rest
// of that robot's frames move later. Copies of frames q and r are a positive pair exactly when
// (q, r) is; copies of one frame are not (they are the robot's own recent past). The name gets a
// suffix such as "x10@100ms".
Run RepeatFrames(const Run& run, int copies, int64_t interval_us);

// Writes `prefix`.frames.csv (image paths as the run holds them) and `prefix`.positives.csv.
Status WriteRun(const Run& run, const std::string& prefix);

// Names of the runs in <dataset>/runs (the <run> of each <run>.frames.csv), sorted; empty when
// the folder does not exist.
std::vector<std::string> ListRuns(const std::string& dataset_dir);

// A dataset given as a folder, or by name under `data_root` (PLACEREC_DATA, or the build's
// ../shared/data): that folder. NotFound when it is neither, naming where it looked and the
// datasets `data_root` holds.
StatusOr<std::string> FindDataset(const std::string& dataset, const std::string& data_root);

}  // namespace placerec
