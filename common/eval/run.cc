#include "common/eval/run.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <system_error>

#include "common/eval/csv_lines.h"
#include "common/util/paths.h"

namespace placerec {
namespace {

using eval_internal::CsvLines;
using eval_internal::JoinNames;
using eval_internal::ParseInt;
using eval_internal::ReadCsvLines;

constexpr char kFramesSuffix[] = ".frames.csv";
constexpr char kPositivesSuffix[] = ".positives.csv";
constexpr char kLayoutHint[] =
    "the dataset directory must hold runs/<run>.frames.csv and runs/<run>.positives.csv as "
    "described in ../shared/data/README.md (PLACEREC_DATA points at the data root)";

std::string JoinPath(const std::string& directory, const std::string& relative) {
  if (directory.empty()) return relative;
  if (directory.back() == '/') return directory + relative;
  return directory + "/" + relative;
}

// The column indices of `names` in `table`, or an error naming the first missing one.
Status FindColumns(const CsvLines& table, const std::vector<std::string>& names,
                   std::vector<int>* columns) {
  columns->clear();
  for (const std::string& name : names) {
    const int column = table.Column(name);
    if (column < 0) {
      std::string expected;
      for (const std::string& n : names) expected += (expected.empty() ? "" : ",") + n;
      return Status::InvalidArgument(table.Where(1) + ": header has no '" + name +
                                     "' column; the header must be " + expected);
    }
    columns->push_back(column);
  }
  return Status::Ok();
}

// Parses a frame index field; `what` names the column in messages.
Status ParseFrameIndex(const CsvLines& table, int line, const std::string& what,
                       const std::string& text, long long* value) {
  if (!ParseInt(text, value)) {
    return Status::InvalidArgument(table.Where(line) + ": " + what + " '" + text +
                                   "' is not an integer");
  }
  return Status::Ok();
}

Status ReadFrames(const std::string& dataset_dir, const std::string& path, Run* run) {
  StatusOr<CsvLines> table_or = ReadCsvLines(path);
  if (!table_or.ok()) return table_or.status();
  const CsvLines& table = *table_or;
  std::vector<int> col;
  PLACEREC_RETURN_IF_ERROR(FindColumns(table, {"frame", "robot", "image", "utime_us"}, &col));
  if (table.rows.empty()) {
    return Status::InvalidArgument(path + " has a header but no frames; a run needs at least one");
  }
  // Last capture time seen for each robot, and the line it was on.
  std::map<std::string, std::pair<int64_t, int>> last_utime;
  for (const eval_internal::CsvLine& row : table.rows) {
    const std::string& frame_text = row.fields[col[0]];
    const std::string& robot = row.fields[col[1]];
    const std::string& image = row.fields[col[2]];
    const std::string& utime_text = row.fields[col[3]];
    const int expected = static_cast<int>(run->frames.size());
    long long frame = 0;
    PLACEREC_RETURN_IF_ERROR(ParseFrameIndex(table, row.line, "frame", frame_text, &frame));
    if (frame != expected) {
      return Status::InvalidArgument(table.Where(row.line) + ": frame is " + frame_text +
                                     ", expected " + std::to_string(expected) +
                                     "; frames must be numbered 0, 1, 2, ... in file order");
    }
    if (robot.empty()) {
      return Status::InvalidArgument(table.Where(row.line) + ": robot is empty; give every " +
                                     "frame the id of the robot that captured it");
    }
    if (image.empty()) {
      return Status::InvalidArgument(table.Where(row.line) + ": image is empty; give the " +
                                     "image path relative to " + dataset_dir);
    }
    long long utime = 0;
    if (!ParseInt(utime_text, &utime)) {
      return Status::InvalidArgument(table.Where(row.line) + ": utime_us '" + utime_text +
                                     "' is not an integer (microseconds since the epoch)");
    }
    auto last = last_utime.find(robot);
    if (last != last_utime.end() && utime < last->second.first) {
      return Status::InvalidArgument(table.Where(row.line) + ": utime_us " + utime_text +
                                     " of robot '" + robot + "' is earlier than " +
                                     std::to_string(last->second.first) + " on line " +
                                     std::to_string(last->second.second) +
                                     "; each robot's frames must be listed in capture order");
    }
    last_utime[robot] = {utime, row.line};

    RunFrame out;
    out.frame = expected;
    out.robot = robot;
    out.image = (!image.empty() && image.front() == '/') ? image : JoinPath(dataset_dir, image);
    out.utime = utime;
    run->frames.push_back(std::move(out));
  }
  return Status::Ok();
}

Status ReadPositives(const std::string& path, Run* run) {
  StatusOr<CsvLines> table_or = ReadCsvLines(path);
  if (!table_or.ok()) {
    if (table_or.status().code() == StatusCode::kNotFound) {
      return Status::NotFound(path + " does not exist; every run needs one (header " +
                              "query,reference), even when it has no revisits");
    }
    return table_or.status();
  }
  const CsvLines& table = *table_or;
  std::vector<int> col;
  PLACEREC_RETURN_IF_ERROR(FindColumns(table, {"query", "reference"}, &col));
  const long long num_frames = static_cast<long long>(run->frames.size());
  for (const eval_internal::CsvLine& row : table.rows) {
    long long query = 0;
    long long reference = 0;
    PLACEREC_RETURN_IF_ERROR(ParseFrameIndex(table, row.line, "query", row.fields[col[0]], &query));
    PLACEREC_RETURN_IF_ERROR(
        ParseFrameIndex(table, row.line, "reference", row.fields[col[1]], &reference));
    for (const long long frame : {query, reference}) {
      if (frame < 0 || frame >= num_frames) {
        return Status::InvalidArgument(table.Where(row.line) + ": frame " + std::to_string(frame) +
                                       " does not exist; the frames file lists frames 0.." +
                                       std::to_string(num_frames - 1));
      }
    }
    if (reference >= query) {
      return Status::InvalidArgument(table.Where(row.line) + ": reference " +
                                     std::to_string(reference) + " is not earlier than query " +
                                     std::to_string(query) +
                                     "; list each pair once, as (later frame, earlier frame)");
    }
    run->positives.insert({static_cast<int>(query), static_cast<int>(reference)});
  }
  return Status::Ok();
}

}  // namespace

StatusOr<Run> LoadRun(const std::string& dataset_dir, const std::string& run_name) {
  if (run_name.empty()) return Status::InvalidArgument("run name is empty");
  if (run_name.find('/') != std::string::npos) {
    return Status::InvalidArgument("run name '" + run_name +
                                   "' contains '/'; give the name only, e.g. corridor_loop");
  }
  const std::string runs_dir = JoinPath(dataset_dir, "runs");
  const std::string frames_path = JoinPath(runs_dir, run_name + kFramesSuffix);
  const std::string positives_path = JoinPath(runs_dir, run_name + kPositivesSuffix);
  if (!PathExists(runs_dir)) {
    return Status::NotFound(runs_dir + " does not exist; " + kLayoutHint);
  }
  if (!PathExists(frames_path)) {
    const std::vector<std::string> available = ListRuns(dataset_dir);
    return Status::NotFound("run '" + run_name + "' not found in " + runs_dir + "; " +
                            (available.empty()
                                 ? std::string("there are no runs there; ") + kLayoutHint
                                 : "available runs: " + JoinNames(available)));
  }

  Run run;
  run.dataset_dir = dataset_dir;
  run.name = run_name;
  PLACEREC_RETURN_IF_ERROR(ReadFrames(dataset_dir, frames_path, &run));
  PLACEREC_RETURN_IF_ERROR(ReadPositives(positives_path, &run));
  run.is_revisit.assign(run.frames.size(), false);
  for (const auto& [query, reference] : run.positives) run.is_revisit[query] = true;
  run.num_revisits =
      static_cast<int>(std::count(run.is_revisit.begin(), run.is_revisit.end(), true));
  return run;
}

std::vector<std::string> ListRuns(const std::string& dataset_dir) {
  std::vector<std::string> names;
  const std::string suffix = kFramesSuffix;
  std::error_code ec;
  std::filesystem::directory_iterator it(JoinPath(dataset_dir, "runs"), ec);
  if (ec) return names;
  // Incremented with an error code: a directory that vanishes midway ends the list, not the
  // process.
  for (; !ec && it != std::filesystem::directory_iterator(); it.increment(ec)) {
    const std::string file = it->path().filename().string();
    std::error_code type_ec;
    if (file.size() > suffix.size() &&
        file.compare(file.size() - suffix.size(), suffix.size(), suffix) == 0 &&
        it->is_regular_file(type_ec)) {
      names.push_back(file.substr(0, file.size() - suffix.size()));
    }
  }
  std::sort(names.begin(), names.end());
  return names;
}

Run RepeatFrames(const Run& run, int copies, int64_t interval_us) {
  if (copies <= 1) return run;
  Run repeated;
  repeated.dataset_dir = run.dataset_dir;
  repeated.name =
      run.name + "_x" + std::to_string(copies) + "@" + std::to_string(interval_us / 1000) + "ms";
  std::map<std::string, int64_t> shift;  // per robot: how much later its frames now come
  std::map<std::string, int64_t> last;   // per robot: the last copy's capture time
  for (const RunFrame& frame : run.frames) {
    int64_t start = frame.utime + shift[frame.robot];
    const auto previous = last.find(frame.robot);
    if (previous != last.end() && start < previous->second + interval_us) {
      start = previous->second + interval_us;
      shift[frame.robot] = start - frame.utime;
    }
    for (int c = 0; c < copies; ++c) {
      RunFrame copy = frame;
      copy.frame = static_cast<int>(repeated.frames.size());
      copy.utime = start + c * interval_us;
      repeated.frames.push_back(copy);
    }
    last[frame.robot] = start + (copies - 1) * interval_us;
  }
  for (const auto& [query, reference] : run.positives) {
    for (int q = 0; q < copies; ++q) {
      for (int r = 0; r < copies; ++r) {
        repeated.positives.insert({query * copies + q, reference * copies + r});
      }
    }
  }
  repeated.is_revisit.assign(repeated.frames.size(), false);
  for (const auto& p : repeated.positives) repeated.is_revisit[p.first] = true;
  for (bool r : repeated.is_revisit) repeated.num_revisits += r ? 1 : 0;
  return repeated;
}

Status WriteRun(const Run& run, const std::string& prefix) {
  std::ofstream frames(prefix + ".frames.csv");
  frames << "frame,robot,image,utime_us\n";
  for (const RunFrame& f : run.frames) {
    frames << f.frame << ',' << f.robot << ',' << f.image << ',' << f.utime << '\n';
  }
  std::ofstream positives(prefix + ".positives.csv");
  positives << "query,reference\n";
  for (const auto& [query, reference] : run.positives) {
    positives << query << ',' << reference << '\n';
  }
  frames.close();
  positives.close();
  if (!frames || !positives) return Status::IoError("cannot write " + prefix + ".*.csv");
  return Status::Ok();
}

Run FirstFrames(const Run& run, int frames) {
  if (frames >= static_cast<int>(run.frames.size())) return run;
  Run cut = run;
  cut.frames.resize(std::max(frames, 0));
  cut.positives.clear();
  for (const auto& p : run.positives) {
    if (p.first < frames) cut.positives.insert(p);
  }
  cut.is_revisit.assign(cut.frames.size(), false);
  cut.num_revisits = 0;
  for (const auto& p : cut.positives) cut.is_revisit[p.first] = true;
  for (bool r : cut.is_revisit) cut.num_revisits += r ? 1 : 0;
  return cut;
}

StatusOr<std::string> FindDataset(const std::string& dataset, const std::string& data_root) {
  if (dataset.empty()) return Status::InvalidArgument("no dataset given (--dataset)");
  std::error_code ec;
  if (std::filesystem::is_directory(dataset, ec)) return dataset;
  const std::string under = JoinPath(data_root, dataset);
  if (std::filesystem::is_directory(under, ec)) return under;
  std::vector<std::string> datasets;
  std::filesystem::directory_iterator it(data_root, ec);
  for (; !ec && it != std::filesystem::directory_iterator(); it.increment(ec)) {
    std::error_code type_ec;
    if (it->is_directory(type_ec)) datasets.push_back(it->path().filename().string());
  }
  std::sort(datasets.begin(), datasets.end());
  return Status::NotFound(
      "no dataset '" + dataset + "': it is no folder, nor one under the data root " + data_root +
      " (PLACEREC_DATA, else the build's default); " +
      (!std::filesystem::is_directory(data_root, ec) ? std::string("that root does not exist")
       : datasets.empty()                            ? std::string("that root holds no datasets")
                                                     : "datasets there: " + JoinNames(datasets)));
}

}  // namespace placerec
