// placerec-eval: evaluation on the real data.
//   placerec-eval run --dataset DIR --run NAME --out OUT [pipeline options]
// feeds a run through the pipeline in-process and writes answers.csv, summary.json,
// pr_curve.png and match pictures into OUT.
//   placerec-eval classify --dataset DIR --split test --segments truth --out OUT
// classifies a labelled dataset's ground-truth object segments (seed Ch. 4, Tables 6.5-6.7).
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <optional>
#include <set>
#include <string>

#include <opencv2/imgcodecs.hpp>

#include "common/eval/run.h"
#include "common/image/image.h"
#include "common/pipeline/flags.h"
#include "common/pipeline/pictures.h"
#include "common/util/logging.h"
#include "common/util/options.h"
#include "common/util/paths.h"
#include "tools/alarm_score.h"
#include "tools/change_eval.h"
#include "tools/classify_command.h"
#include "tools/eval_runner.h"
#include "tools/segment_command.h"

namespace placerec {
namespace {

constexpr char kUsage[] =
    "placerec-eval COMMAND [options]\n\n"
    "Commands:\n"
    "  run       feed a place-recognition run through the pipeline and score it\n"
    "  analyze   draw one frame's segmentation, keypoints and objects\n"
    "  segment   segment a labelled dataset's split and score it (seed eq. 6.2)\n"
    "  classify  classify a labelled dataset's object segments (seed Ch. 4, Tables 6.5-6.7)\n"
    "  change    measure scene-change alarms (seed §7.2.4) with objects pasted into revisits\n"
    "  alarms    score the alarms placerec-client watch recorded while a changed run was "
    "replayed\n\n"
    "'placerec-eval COMMAND --help' lists the options of a command.";

// A dataset given by name (e.g. gardens_point) is looked up under PLACEREC_DATA or
// ../shared/data when it is not a directory itself.
StatusOr<std::string> ResolveDataset(const std::string& dataset) {
  return FindDataset(dataset, DataDir("", PLACEREC_DEFAULT_DATA_DIR));
}

// The run `run_name` of a dataset given as ResolveDataset takes it.
StatusOr<Run> LoadNamedRun(const std::string& dataset, const std::string& run_name) {
  StatusOr<std::string> dir = ResolveDataset(dataset);
  if (!dir.ok()) return dir.status();
  return LoadRun(*dir, run_name);
}

int RunCommand(int argc, char** argv) {
  std::string dataset;
  std::string run_name;
  std::string out;
  EvalOptions eval;
  bool quiet = false;
  int repeat = 1;
  double repeat_interval_ms = 100.0;
  RecognizerOptions options;
  FlagParser parser(
      "placerec-eval run --dataset DIR --run NAME --out OUT [options]\n\n"
      "Feeds every frame of a run (layout of shared/data/README.md) through the pipeline in\n"
      "order, each frame compared only with earlier ones, and writes OUT/answers.csv\n"
      "(frame,reference,score), OUT/candidates.csv (every place returned per frame),\n"
      "OUT/summary.json, OUT/pr_curve.png and OUT/matches/*.jpg.");
  parser.AddRequired("dataset", &dataset,
                     "dataset directory, or its name under PLACEREC_DATA / ../shared/data");
  parser.AddRequired("run", &run_name, "run name (DIR/runs/NAME.frames.csv)");
  parser.AddRequired("out", &out, "output directory (created if missing)");
  parser.Add("db", &eval.db_path, "SQLite map file to build (default: a map in memory)");
  parser.Add("pictures", &eval.pictures, "match pictures to draw");
  parser.Add("max-frames", &eval.max_frames,
             "stop before this frame (0: all); without --first-frame, a frame count");
  parser.Add("first-frame", &eval.first_frame,
             "feed from this frame on (0: the first), continuing the map --db that a run with "
             "--max-frames FIRST built, as a restarted server would; scores its revisits only");
  parser.Add("frame-width", &eval.frame_width,
             "scale every frame to this many pixels wide as it is read, as a camera of that "
             "resolution would send it (0: as recorded; e.g. 160 or 320)");
  parser.Add("repeat", &repeat,
             "send every frame this many times, repeat-interval-ms apart (a faster camera or a "
             "robot standing still); OUT/run.frames.csv and run.positives.csv hold the fed run");
  parser.Add("repeat-interval-ms", &repeat_interval_ms,
             "capture-time interval between the copies of a frame (100: 10 Hz, 33.3: 30 Hz)");
  parser.AddSwitch("print-loops", &eval.print_loop_closures,
                   "print each loop closure as it is found");
  parser.AddSwitch("quiet", &quiet, "no progress line");
  AddRecognizerFlags(&parser, &options);
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 2, "placerec-eval run")) {
    return *exit;
  }
  std::string error;
  if (!options.Check(&error)) {
    std::fprintf(stderr, "placerec-eval run: %s\n", error.c_str());
    return 2;
  }
  if (eval.frame_width != 0 && (eval.frame_width < 16 || eval.frame_width > 8192)) {
    std::fprintf(stderr, "placerec-eval run: --frame-width must be 0 or in [16, 8192] pixels\n");
    return 2;
  }
  if (repeat < 1 || repeat_interval_ms <= 0) {
    std::fprintf(stderr, "placerec-eval run: --repeat must be >= 1 and --repeat-interval-ms > 0\n");
    return 2;
  }
  eval.out_dir = out;
  eval.progress = !quiet;
  StatusOr<Run> run = LoadNamedRun(dataset, run_name);
  if (!run.ok()) {
    std::fprintf(stderr, "placerec-eval run: %s\n", run.status().ToString().c_str());
    return 1;
  }
  if (repeat > 1) {
    *run = RepeatFrames(*run, repeat, static_cast<int64_t>(repeat_interval_ms * 1000.0));
    if (!MakeDirectories(out)) {
      std::fprintf(stderr, "placerec-eval run: cannot create or write in %s\n", out.c_str());
      return 1;
    }
    const Status written = WriteRun(*run, out + "/run");
    if (!written.ok()) {
      std::fprintf(stderr, "placerec-eval run: %s\n", written.ToString().c_str());
      return 1;
    }
  }
  StatusOr<EvalReport> report = EvaluateRun(*run, options, eval);
  if (!report.ok()) {
    std::fprintf(stderr, "placerec-eval run: %s\n", report.status().ToString().c_str());
    return 1;
  }
  const nlohmann::json& s = report->summary;
  std::printf(
      "%s/%s: %d frames, %d revisits, %d answered\n"
      "  recall at 100%% precision %.3f, max F1 %.3f, average precision %.3f\n"
      "  at the decision threshold (score >= %.0f): %d loop closures, precision %.3f, recall "
      "%.3f\n"
      "  descriptors stored / extracted: %lld / %lld = %.3f\n"
      "  median frame time %.1f ms (SIFT %.1f ms)\n"
      "  wrote %s/answers.csv, summary.json, pr_curve.png, matches/\n",
      s["dataset"].get<std::string>().c_str(), s["run"].get<std::string>().c_str(),
      s["frames"].get<int>(), s["revisit_frames"].get<int>(), s["answered_frames"].get<int>(),
      s["recall_at_100_precision"].get<double>(), s["max_f1"].get<double>(),
      s["average_precision"].get<double>(), s["decision"]["min_score"].get<double>(),
      s["loop_closures"].get<int>(), s["decision"]["precision"].get<double>(),
      s["decision"]["recall"].get<double>(), s["descriptors_stored"].get<long long>(),
      s["descriptors_extracted"].get<long long>(), s["stored_over_extracted"].get<double>(),
      s["time"]["frame_total"]["median_ms"].get<double>(),
      s["time"].contains("sift") ? s["time"]["sift"]["median_ms"].get<double>() : 0.0, out.c_str());
  return 0;
}

// cv::imwrite, false when the file was not written (it returns false, or throws for some causes).
bool WritePicture(const std::string& file, const cv::Mat& picture) {
  try {
    return cv::imwrite(file, picture);
  } catch (const cv::Exception&) {
    return false;
  }
}

int AnalyzeCommand(int argc, char** argv) {
  std::vector<std::string> images;
  std::string out = ".";
  RecognizerOptions options;
  FlagParser parser(
      "placerec-eval analyze IMAGE... [--out DIR] [options]\n\n"
      "Runs the stateless half of the pipeline (SIFT, segmentation, objects) on each image and\n"
      "writes DIR/<name>_analysis.png (<name>_2_analysis.png, ... for a name given before):\n"
      "segments tinted with boundaries, keypoints as dots, objects outlined with their SIFT\n"
      "count and dominant colour invariants.");
  parser.AddPositional("image", &images, "image files");
  parser.Add("out", &out, "output directory");
  AddRecognizerFlags(&parser, &options);
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 2, "placerec-eval analyze")) {
    return *exit;
  }
  std::string error;
  if (!options.Check(&error)) {
    std::fprintf(stderr, "placerec-eval analyze: %s\n", error.c_str());
    return 2;
  }
  if (images.empty()) {
    std::fprintf(stderr, "placerec-eval analyze: give at least one image (see --help)\n");
    return 2;
  }
  if (!MakeDirectories(out)) {
    std::fprintf(stderr, "placerec-eval analyze: cannot create or write in %s\n", out.c_str());
    return 1;
  }
  StatusOr<std::unique_ptr<Segmenter>> segmenter = MakeSegmenter(options.analyzer);
  if (!segmenter.ok()) {
    std::fprintf(stderr, "placerec-eval analyze: %s\n", segmenter.status().message().c_str());
    return 1;
  }
  const FrameAnalyzer analyzer(options.analyzer, std::move(*segmenter));
  std::set<std::string> written;  // pictures of this call: same-named images do not overwrite
  for (const std::string& path : images) {
    StatusOr<cv::Mat> image = ReadImageFile(path);
    if (!image.ok()) {
      std::fprintf(stderr, "placerec-eval analyze: %s\n", image.status().ToString().c_str());
      return 1;
    }
    // As the server refuses frames of more pixels (--max-image-pixels): the pipeline at full
    // size on a 10000 x 8000 photo took 4 minutes and 19 GB.
    const int64_t pixels = int64_t{image->cols} * image->rows;
    const int cap = ProcessedWidthCap(image->size(), options.analyzer.max_image_width);
    const int64_t processed_width = cap > 0 ? std::min(image->cols, cap) : image->cols;
    const int64_t processed_pixels =
        pixels * processed_width * processed_width / (int64_t{image->cols} * image->cols);
    if (processed_pixels > DecodeOptions().max_pixels) {
      std::fprintf(
          stderr,
          "placerec-eval analyze: %s is %dx%d, more than the %lld pixels the server "
          "takes; give --max-image-width (e.g. the default, 960) to analyze it scaled down\n",
          path.c_str(), image->cols, image->rows,
          static_cast<long long>(DecodeOptions().max_pixels));
      return 2;
    }
    const FrameObservation observation = analyzer.Analyze(*image);
    const cv::Mat picture = DrawAnalysis(*image, observation);
    std::string name = path.substr(path.find_last_of('/') + 1);
    name = name.substr(0, name.find_last_of('.'));
    std::string file = out + "/" + name + "_analysis.png";
    for (int n = 2; !written.insert(file).second; ++n) {
      file = out + "/" + name + "_" + std::to_string(n) + "_analysis.png";
    }
    if (!WritePicture(file, picture)) {
      std::fprintf(stderr, "placerec-eval analyze: cannot write %s; choose another --out\n",
                   file.c_str());
      return 1;
    }
    std::printf(
        "%s: %dx%d, %d keypoints, %d segments, %d objects holding %d keypoints -> %s\n",
        path.c_str(), image->cols, image->rows, observation.features.size(),
        observation.segmentation.size(), static_cast<int>(observation.objects.size()),
        [&] {
          int n = 0;
          for (const SceneObject& o : observation.objects) n += o.sift_count();
          return n;
        }(),
        file.c_str());
  }
  return 0;
}

int ChangeCommand(int argc, char** argv) {
  std::string dataset;
  std::string run_name;
  std::string objects = "camvid";
  ChangeEvalOptions eval;
  bool quiet = false;
  int seed = 1;
  RecognizerOptions options;
  FlagParser parser(
      "placerec-eval change --dataset DIR --run NAME --out OUT [options]\n\n"
      "Measures scene-change detection (seed §7.2.4) on a run's true revisits. Frames are fed in\n"
      "order; each revisit is first asked as a query: every second one unchanged, the others\n"
      "with a real object (car, pedestrian, sign, bicyclist) cut by its ground-truth mask from\n"
      "the test split of --objects pasted in at 1-10 % of the frame (random position and size,\n"
      "fixed --seed, feathered colour-matched edges), every --removal-every-th of them instead\n"
      "with a stored landmark painted over with its surroundings (the frame's object holding the\n"
      "most verified points of the place the unchanged frame is matched to). Then the frame is\n"
      "inserted as recorded. Writes OUT/change.json (detection_recall by size band with IoU >= "
      "0.3,\n"
      "false_alarm_rate on the unchanged revisits, and on those compared, localisation_iou\n"
      "median) and\n"
      "OUT/pictures/{hit,miss,false_alarm}_*.png (truth green, alarms red/yellow, stored place\n"
      "right).");
  parser.AddRequired("dataset", &dataset,
                     "dataset directory, or its name under PLACEREC_DATA / ../shared/data");
  parser.AddRequired("run", &run_name, "run name (DIR/runs/NAME.frames.csv)");
  parser.AddRequired("out", &eval.out_dir, "output directory (created if missing)");
  parser.Add("objects", &objects,
             "labelled datasets (comma-separated names or folders) whose test-split objects are "
             "pasted");
  parser.Add("seed", &seed, "random seed of objects, sizes and positions");
  parser.Add("paste-colour-shift", &eval.colour_shift,
             "how far a pasted object's mean Lab colour moves towards the region it covers (0: "
             "the object's own colours, 1: the region's mean; the edges are feathered either "
             "way)");
  parser.Add("removal-every", &eval.removal_every,
             "every N-th changed revisit is a removal instead of a paste (0: none)");
  parser.Add("pictures", &eval.pictures, "pictures per kind (hit, miss, false alarm)");
  parser.Add("max-frames", &eval.max_frames, "stop after this many frames (0: all)");
  parser.Add("write-run", &eval.write_run_dir,
             "also write the run as changed, to replay through a live server while "
             "placerec-client watch records the alarms (scripts/watch-changes.sh): "
             "DIR/runs/NAME_changed.{frames,positives,changes}.csv and DIR/images; the changed "
             "frames are inserted there, not only asked");
  parser.AddSwitch("quiet", &quiet, "no progress line");
  AddRecognizerFlags(&parser, &options);
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 2, "placerec-eval change")) {
    return *exit;
  }
  std::string error;
  if (!options.Check(&error)) {
    std::fprintf(stderr, "placerec-eval change: %s\n", error.c_str());
    return 2;
  }
  eval.seed = static_cast<uint64_t>(seed);
  eval.progress = !quiet;
  for (size_t start = 0; start <= objects.size();) {
    const size_t end = std::min(objects.find(',', start), objects.size());
    if (end > start) {
      StatusOr<std::string> dir = ResolveDataset(objects.substr(start, end - start));
      if (!dir.ok()) {
        std::fprintf(stderr, "placerec-eval change: --objects: %s\n",
                     dir.status().message().c_str());
        return 1;
      }
      eval.object_datasets.push_back(*dir);
    }
    start = end + 1;
  }
  StatusOr<Run> run = LoadNamedRun(dataset, run_name);
  if (!run.ok()) {
    std::fprintf(stderr, "placerec-eval change: %s\n", run.status().ToString().c_str());
    return 1;
  }
  StatusOr<nlohmann::json> report = EvaluateChanges(*run, options, eval);
  if (!report.ok()) {
    std::fprintf(stderr, "placerec-eval change: %s\n", report.status().ToString().c_str());
    return 1;
  }
  const nlohmann::json& j = *report;
  std::printf(
      "%s %s: detection_recall %.3f (objects >= 2%%: %.3f), false_alarm_rate %.3f (of the "
      "compared: %.3f), localisation_iou %.2f; removals found %.3f; change %.1f ms vs SIFT %.1f "
      "ms -> %s\n",
      j["dataset"].get<std::string>().c_str(), j["run"].get<std::string>().c_str(),
      j["detection_recall"].get<double>(), j["detection_recall_2pct"].get<double>(),
      j["false_alarm_rate"].get<double>(), j["false_alarm_rate_compared"].get<double>(),
      j["localisation_iou"].get<double>(), j["removed"]["detection_recall"].get<double>(),
      j["change_ms_median"].get<double>(), j["sift_ms_median"].get<double>(),
      (eval.out_dir + "/change.json").c_str());
  return 0;
}

int AlarmsCommand(int argc, char** argv) {
  std::string changes;
  std::string alarms;
  std::string out;
  double min_iou = ChangeEvalOptions().min_iou;
  FlagParser parser(
      "placerec-eval alarms --changes FILE --alarms FILE --out OUT [options]\n\n"
      "Scores scene-change alarms watched live (seed §7.2.4): a run changed by\n"
      "'placerec-eval change --write-run DIR' was replayed through a server with\n"
      "'placerec-client run' while 'placerec-client watch --out W' recorded the alarms. Each\n"
      "revisit of DIR/runs/NAME_changed.changes.csv is matched with W/alarms.csv by robot and\n"
      "sequence number (the run's frame index) and scored as 'placerec-eval change' scores its\n"
      "answers. Writes OUT/alarms.json. scripts/watch-changes.sh runs all of it.");
  parser.AddRequired("changes", &changes, "the changed run's changes file");
  parser.AddRequired("alarms", &alarms, "alarms.csv of placerec-client watch --out");
  parser.AddRequired("out", &out, "output directory (created if missing)");
  parser.Add("min-iou", &min_iou, "an alarm finds a change with at least this box IoU");
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 2, "placerec-eval alarms")) {
    return *exit;
  }
  if (!(min_iou > 0 && min_iou <= 1)) {
    std::fprintf(stderr, "placerec-eval alarms: --min-iou must be in (0, 1]\n");
    return 2;
  }
  StatusOr<std::vector<ChangeCase>> cases = LoadChangeCases(changes);
  StatusOr<std::vector<WatchedAlarm>> watched =
      cases.ok() ? LoadWatchedAlarms(alarms) : StatusOr<std::vector<WatchedAlarm>>(cases.status());
  if (!watched.ok()) {
    std::fprintf(stderr, "placerec-eval alarms: %s\n", watched.status().ToString().c_str());
    return 1;
  }
  if (!MakeDirectories(out)) {
    std::fprintf(stderr, "placerec-eval alarms: cannot create or write in %s\n", out.c_str());
    return 1;
  }
  const nlohmann::json j = ScoreAlarms(*cases, *watched, min_iou);
  if (!(std::ofstream(out + "/alarms.json") << j.dump(2) << "\n")) {
    std::fprintf(stderr, "placerec-eval alarms: cannot write %s/alarms.json\n", out.c_str());
    return 1;
  }
  std::printf(
      "%zu alarms on %zu revisits: detection_recall %.3f (objects >= 2%%: %.3f), "
      "false_alarm_rate %.3f, localisation_iou %.2f; removals found %.3f; %d frames that are no "
      "revisit raised alarms -> %s/alarms.json\n",
      watched->size(), cases->size(), j["detection_recall"].get<double>(),
      j["detection_recall_2pct"].get<double>(), j["false_alarm_rate"].get<double>(),
      j["localisation_iou"].get<double>(), j["removed"]["detection_recall"].get<double>(),
      j["frames_alarmed_elsewhere"].get<int>(), out.c_str());
  return 0;
}

}  // namespace
}  // namespace placerec

int main(int argc, char** argv) {
  placerec::InitLogging(argv[0]);
  if (argc < 2 || std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0) {
    std::printf("%s\n", placerec::kUsage);
    return argc < 2 ? 2 : 0;
  }
  if (std::strcmp(argv[1], "run") == 0) return placerec::RunCommand(argc, argv);
  if (std::strcmp(argv[1], "analyze") == 0) return placerec::AnalyzeCommand(argc, argv);
  if (std::strcmp(argv[1], "change") == 0) return placerec::ChangeCommand(argc, argv);
  if (std::strcmp(argv[1], "alarms") == 0) return placerec::AlarmsCommand(argc, argv);
  if (std::strcmp(argv[1], "segment") == 0) {
    return placerec::SegmentCommand(argc, argv, placerec::DataDir("", PLACEREC_DEFAULT_DATA_DIR));
  }
  if (std::strcmp(argv[1], "classify") == 0) {
    return placerec::ClassifyCommand(argc, argv, placerec::DataDir("", PLACEREC_DEFAULT_DATA_DIR));
  }
  std::fprintf(stderr, "placerec-eval: unknown command '%s'\n%s\n", argv[1], placerec::kUsage);
  return 2;
}
