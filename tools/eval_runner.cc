#include "tools/eval_runner.h"

#include <cstdio>
#include <fstream>
#include <iomanip>
#include <iterator>
#include <map>
#include <sstream>

#include <opencv2/imgcodecs.hpp>

#include "common/eval/plots.h"
#include "common/eval/stats.h"
#include "common/image/image.h"
#include "common/pipeline/object_classes.h"
#include "common/pipeline/pictures.h"
#include "common/storage/sqlite_store.h"
#include "common/util/logging.h"
#include "common/util/paths.h"
#include "common/util/progress.h"
#include "common/util/timer.h"

namespace placerec {
namespace {

struct FrameRecord {
  bool has_match = false;
  bool loop_closure = false;  // the recognizer's decision
  PlaceMatch best;
  double scale = 1.0;
};

std::string Fixed(double value, int digits) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(digits) << value;
  return out.str();
}

nlohmann::json OptionsJson(const RecognizerOptions& o) {
  nlohmann::json j;
  j["max_image_width"] = o.analyzer.max_image_width;
  j["small_frame_width"] = o.analyzer.small_frame_width;
  j["upscaled_width"] = o.analyzer.upscaled_width;
  const bool organization = o.analyzer.segmentation == SegmentationMethod::kOrganization;
  const SuperpixelOptions& superpixels =
      organization ? o.analyzer.organization.superpixels : o.analyzer.superpixels;
  j["segmentation"] = organization ? "organization" : "superpixels";
  j["segmentation_width"] = superpixels.working_width;
  j["fh_k"] = superpixels.k;
  j["fh_min_size"] = superpixels.min_size;
  j["colour_merge_distance"] = o.analyzer.superpixels.colour_merge_distance;
  j["sift_contrast_threshold"] = o.analyzer.features.contrast_threshold;
  j["object_min_keypoints"] = o.analyzer.objects.min_keypoints;
  j["landmark_history"] = o.landmarks.history_frames;
  j["landmark_min_matches"] = o.landmarks.matching.min_matches;
  j["query_objects"] = o.query_objects == QueryObjects::kAll ? "all" : "landmarks";
  j["store_tracked_only"] = o.store_tracked_descriptors_only;
  j["use_count_range"] = o.index.use_count_range;
  j["count_range"] = {o.index.count_range_low, o.index.count_range_high};
  j["use_colour_filter"] = o.index.use_colour_filter;
  j["colour_tolerance"] = o.index.colour.tolerance;
  j["match_min"] = o.index.matching.min_matches;
  j["match_ratio"] = o.index.matching.ratio;
  j["match_knn"] = o.index.matching.knn;
  j["vote_places"] = o.index.vote_places;
  j["exact_places"] = o.index.exact_places;
  j["exact_route_neighbours"] = o.index.exact_route_neighbours;
  j["exact_max_comparisons"] = o.index.exact_max_comparisons;
  j["index_search"] = o.index.search == IndexSearch::kFlann ? "flann" : "exhaustive";
  j["min_same_robot_gap_seconds"] = o.recent_past.min_gap_seconds;
  j["resume_within_seconds"] = o.recent_past.resume_within_seconds;
  j["away_seconds"] = o.recent_past.away_seconds;
  j["geometric_verification"] = o.loop.geometric_verification;
  j["sequence_frames"] = o.sequence.frames;
  j["objects_include_background"] = o.analyzer.objects.include_background;
  j["recognition"] = o.mode == RecognitionMode::kSeed ? "seed" : "default";
  j["object_classes"] = o.classes.enabled;
  j["drop_movable"] = o.classes.drop_movable;
  j["min_movable_confidence"] = o.classes.min_movable_confidence;
  j["loop_min_score"] = o.loop.min_score;
  return j;
}

// What feeding the frames gathers, beyond the answers.
struct FeedTotals {
  std::vector<FrameRecord> records;
  std::map<std::string, std::vector<double>> stage_ms;
  std::vector<double> total_ms;
  std::vector<double> frame_scale;
  int64_t extracted = 0;
  int64_t stored = 0;
  int64_t objects = 0;
  int64_t landmarks = 0;
  int64_t movable_landmarks = 0;                  // left out of the map for their class
  std::map<std::string, int64_t> stored_classes;  // stored landmarks per object class
  int loop_closures = 0;
  // candidates.csv: every place returned per frame (--max-matches of them), best first.
  std::string candidates_csv =
      "frame,rank,reference,robot,score,inliers,matched_descriptors,"
      "matched_landmarks,log_scale,classes\n";
};

// Precision and recall at the decision threshold.
struct DecisionCounts {
  int tp = 0;
  int fp = 0;
  int fp_same_robot = 0;  // wrong loop closures to the robot's own frames
};

// A frame of the run as the simulated camera sends it (eval.frame_width).
StatusOr<cv::Mat> ReadFrame(const std::string& path, const EvalOptions& eval) {
  StatusOr<cv::Mat> image = ReadImageFile(path);
  if (!image.ok() || eval.frame_width <= 0) return image;
  return ResizeToWidth(*image, eval.frame_width);
}

// The map the run builds (SQLite, in memory unless `eval.db_path` names a file).
StatusOr<std::unique_ptr<PlaceMap>> OpenMap(const RecognizerOptions& options,
                                            const EvalOptions& eval) {
  SqliteStoreOptions store_options;
  StatusOr<std::unique_ptr<LandmarkStore>> store =
      OpenSqliteStore(eval.db_path.empty() ? ":memory:" : eval.db_path, store_options);
  if (!store.ok()) return store.status();
  // The index as the mode uses it (the seed's recognition: no vote places, no exact matching).
  return PlaceMap::Open(std::move(*store), EffectiveOptions(options).index);
}

// One stdout line for a loop closure found at `frame`.
void PrintLoopClosure(const Run& run, const RunFrame& frame, const RecognitionResult& result,
                      const Answer& answer, const EvalOptions& eval, ProgressLine* progress) {
  const PlaceMatch& best = result.matches.front();
  const bool correct = run.IsPositive(frame.frame, answer.reference);
  if (eval.progress) progress->Clear();
  std::printf(
      "loop closure: frame %d (%s) revisits frame %lld (%s), score %.0f, %d "
      "landmarks matched%s\n",
      frame.frame, frame.robot.c_str(), static_cast<long long>(best.place.sequence),
      best.place.robot.c_str(), best.score, best.matched_landmarks,
      run.is_revisit[frame.frame] ? (correct ? "  [correct]" : "  [wrong place]")
                                  : "  [not a revisit]");
  std::fflush(stdout);
}

// Feeds frames [`first`, `frames`) of `run` through `recognizer`, appending one answer per frame
// to `report` and the counts and timings to `totals` (indexed by frame).
Status FeedFrames(const Run& run, const EvalOptions& eval, int first, int frames,
                  const Timer& run_timer, Recognizer& recognizer, EvalReport* report,
                  FeedTotals* totals) {
  FrameObservation last_observation;
  const int fed = frames - first;
  ProgressLine progress(static_cast<size_t>(fed), static_cast<size_t>(fed / 10));

  for (int f = first; f < frames; ++f) {
    const RunFrame& frame = run.frames[f];
    Timer frame_timer;
    // A frame sent again (a repeated run) is analysed once: analysis is deterministic.
    double decode_ms = 0;
    if (f == first || frame.image != run.frames[f - 1].image) {
      StatusOr<cv::Mat> image = ReadFrame(frame.image, eval);
      if (!image.ok()) return image.status();
      decode_ms = frame_timer.ElapsedMs();
      last_observation = recognizer.Analyze(*image);
    }
    FrameRequest request;
    request.robot = frame.robot;
    request.sequence = frame.frame;
    request.utime = frame.utime;
    RecognitionResult result = recognizer.Recognize(request, last_observation);
    if (!result.status.ok()) {
      // A frame the map --db refuses (its robot and sequence stored, or not after the robot's
      // last) is the usual InvalidArgument of a run fed into a map that already holds it.
      std::string advice;
      if (!eval.db_path.empty() && result.status.code() == StatusCode::kInvalidArgument) {
        advice = "; if the map " + eval.db_path +
                 " already holds this run's frames, give a new --db, or --first-frame after "
                 "the last frame it holds (placerec-map info --db " +
                 eval.db_path + " shows each robot's sequences)";
      }
      return Status(result.status.code(),
                    "frame " + std::to_string(f) + ": " + result.status.message() + advice);
    }
    totals->total_ms.push_back(frame_timer.ElapsedMs());
    totals->stage_ms["decode"].push_back(decode_ms);
    for (const auto& [stage, ms] : result.timings) totals->stage_ms[stage].push_back(ms);
    totals->extracted += result.keypoints;
    totals->stored += result.stored_descriptors;
    totals->objects += result.objects;
    totals->landmarks += result.landmarks;
    totals->movable_landmarks += result.movable_landmarks;
    for (const std::string& name : result.stored_classes) {
      ++totals->stored_classes[name.empty() ? "(none)" : name];
    }

    Answer answer;
    answer.frame = frame.frame;
    if (!result.matches.empty()) {
      const PlaceMatch& best = result.matches.front();
      answer.reference = static_cast<int>(best.place.sequence);
      answer.score = best.score;
      totals->records[f].has_match = true;
      totals->records[f].best = best;
    }
    for (size_t rank = 0; rank < result.matches.size(); ++rank) {
      const PlaceMatch& m = result.matches[rank];
      char row[160];
      std::snprintf(row, sizeof(row), "%d,%zu,%lld,%s,%.6g,%d,%d,%d,%.4f,", frame.frame, rank,
                    static_cast<long long>(m.place.sequence), m.place.robot.c_str(), m.score,
                    m.inliers, m.matched_descriptors, m.matched_landmarks, m.log_scale);
      totals->candidates_csv += row;
      // Classes of the matched landmarks, "building:3;sign:1".
      for (size_t c = 0; c < m.landmark_classes.size(); ++c) {
        totals->candidates_csv += (c > 0 ? ";" : "") + m.landmark_classes[c].first + ":" +
                                  std::to_string(m.landmark_classes[c].second);
      }
      totals->candidates_csv += "\n";
    }
    totals->frame_scale[f] = result.image_scale;
    report->answers.push_back(answer);
    totals->records[f].loop_closure = result.loop_closure;
    if (result.loop_closure) {
      ++totals->loop_closures;
      if (eval.print_loop_closures) PrintLoopClosure(run, frame, result, answer, eval, &progress);
    }
    if (eval.progress) {
      const int done = f - first + 1;
      const double elapsed = run_timer.ElapsedMs() / 1000.0;
      const double eta = elapsed / done * (fed - done);
      progress.Report(static_cast<size_t>(done),
                      "[%4d/%d] %5.1f%%  %s  kp %4d  obj %3d  lm %3d  map %6lld lm  loops %d  "
                      "eta %4.0fs",
                      f + 1, frames, 100.0 * done / fed, frame.robot.c_str(), result.keypoints,
                      result.objects, result.landmarks,
                      static_cast<long long>(result.map.landmarks), totals->loop_closures, eta);
    }
  }
  return Status::Ok();
}

// The recognizer's loop closures (score >= loop-min-score by default; the seed's step 6 with
// --recognition seed) against the truth.
DecisionCounts CountDecisions(const Run& run, const Run& scored, const std::vector<Answer>& answers,
                              const std::vector<FrameRecord>& records) {
  DecisionCounts counts;
  for (const Answer& a : answers) {
    if (a.reference < 0 || !records[a.frame].loop_closure) continue;
    if (scored.IsPositive(a.frame, a.reference)) {
      ++counts.tp;
    } else {
      ++counts.fp;
      // A map file from another run may answer with a place beyond this run's frames.
      if (a.reference < static_cast<int>(run.frames.size()) &&
          run.frames[a.frame].robot == run.frames[a.reference].robot) {
        ++counts.fp_same_robot;
      }
    }
  }
  return counts;
}

// Median and 90th percentile of each stage's time and of the whole frame.
nlohmann::json TimingJson(const FeedTotals& totals) {
  nlohmann::json timing;
  for (const auto& [stage, values] : totals.stage_ms) {
    timing[stage] = {{"median_ms", Median(values)}, {"p90_ms", Percentile(values, 90)}};
  }
  timing["frame_total"] = {{"median_ms", Median(totals.total_ms)},
                           {"p90_ms", Percentile(totals.total_ms, 90)}};
  return timing;
}

// What summary.json holds. `run_timer` is read here, for "wall_seconds".
nlohmann::json SummaryJson(const Run& run, int frames, const RecognizerOptions& options,
                           const EvalReport& report, const DecisionCounts& decisions,
                           const FeedTotals& totals, const PlaceMap& map,
                           const Recognizer& recognizer, const Timer& run_timer) {
  nlohmann::json s = ScoreSummary(run, frames, report.score);
  s["loop_closures"] = totals.loop_closures;
  s["decision"] = DecisionSummary(decisions.tp, decisions.fp, report.score.revisit_frames);
  s["decision"]["min_score"] = options.loop.min_score;
  s["decision"]["false_loop_closures_same_robot"] = decisions.fp_same_robot;
  s["descriptors_extracted"] = totals.extracted;
  s["descriptors_stored"] = totals.stored;
  s["stored_over_extracted"] =
      totals.extracted > 0 ? static_cast<double>(totals.stored) / totals.extracted : 0.0;
  s["objects"] = totals.objects;
  s["landmarks"] = totals.landmarks;
  s["movable_landmarks_left_out"] = totals.movable_landmarks;
  s["stored_landmark_classes"] = totals.stored_classes;
  const MapCounts counts = map.Counts();
  s["map"] = {{"places", counts.places},
              {"landmarks", counts.landmarks},
              {"descriptors", counts.descriptors}};
  s["time"] = TimingJson(totals);
  s["wall_seconds"] = run_timer.ElapsedMs() / 1000.0;
  s["segmentation"] = recognizer.segmenter().name();
  s["options"] = OptionsJson(options);
  return s;
}

// answers.csv, candidates.csv, summary.json and pr_curve.png in `out_dir`.
Status WriteOutputs(const Run& run, const std::string& out_dir, const EvalReport& report,
                    const FeedTotals& totals) {
  PLACEREC_RETURN_IF_ERROR(WriteAnswers(out_dir + "/answers.csv", report.answers));
  {
    std::ofstream out(out_dir + "/candidates.csv");
    if (!out) return Status::IoError("cannot write " + out_dir + "/candidates.csv");
    out << totals.candidates_csv;
  }
  {
    std::ofstream out(out_dir + "/summary.json");
    if (!out) return Status::IoError("cannot write " + out_dir + "/summary.json");
    out << report.summary.dump(2) << "\n";
  }
  PrCurve curve;
  curve.label = "placerec (R@100P " + Fixed(report.score.recall_at_100_precision, 2) + ", max F1 " +
                Fixed(report.score.max_f1, 2) + ")";
  curve.score = report.score;
  return WritePrCurvePng(out_dir + "/pr_curve.png", run.name + ": precision-recall", {curve});
}

// Which answers (indices into report.answers) get a match picture: the strongest correct ones,
// then the strongest wrong ones (a third of `pictures` at most); each with whether it is correct.
std::vector<std::pair<int, bool>> ChoosePictures(const Run& scored, const EvalReport& report,
                                                 const FeedTotals& totals, int pictures) {
  std::vector<int> correct;
  std::vector<int> wrong;
  for (int i = 0; i < static_cast<int>(report.answers.size()); ++i) {
    const Answer& answer = report.answers[i];
    if (!totals.records[answer.frame].has_match) continue;
    (scored.IsPositive(answer.frame, answer.reference) ? correct : wrong).push_back(i);
  }
  auto by_score = [&](int a, int b) { return report.answers[a].score > report.answers[b].score; };
  std::sort(correct.begin(), correct.end(), by_score);
  std::sort(wrong.begin(), wrong.end(), by_score);
  const int n_wrong = std::min<int>(wrong.size(), pictures / 3);
  const int n_correct = std::min<int>(correct.size(), pictures - n_wrong);
  std::vector<std::pair<int, bool>> chosen;
  for (int i = 0; i < n_correct; ++i) chosen.emplace_back(correct[i], true);
  for (int i = 0; i < n_wrong; ++i) chosen.emplace_back(wrong[i], false);
  return chosen;
}

// Match pictures in `out_dir`/matches: the strongest correct answers and the strongest wrong ones.
Status WriteMatchPictures(const Run& run, const Run& scored, int first, const EvalOptions& eval,
                          const EvalReport& report, const FeedTotals& totals,
                          Recognizer& recognizer) {
  const std::string dir = eval.out_dir + "/matches";
  if (!MakeDirectories(dir)) return Status::IoError("cannot create or write in " + dir);
  for (const auto& [i, is_correct] : ChoosePictures(scored, report, totals, eval.pictures)) {
    const int f = report.answers[i].frame;
    const int reference = report.answers[i].reference;
    // A place beyond the frames fed (a map file from another run) has no picture here.
    if (reference >= static_cast<int>(totals.frame_scale.size())) continue;
    StatusOr<cv::Mat> query = ReadFrame(run.frames[f].image, eval);
    StatusOr<cv::Mat> ref = ReadFrame(run.frames[reference].image, eval);
    if (!query.ok() || !ref.ok()) continue;
    const FrameObservation observation = recognizer.Analyze(*query);
    // A reference fed by an earlier call (before `first`): its scale as the analysis sets it.
    const double reference_scale =
        reference >= first ? totals.frame_scale[reference] : recognizer.Analyze(*ref).scale;
    const std::string caption =
        "frame " + std::to_string(f) + " (" + run.frames[f].robot + ") -> frame " +
        std::to_string(reference) + " (" + run.frames[reference].robot + ")  score " +
        Fixed(report.answers[i].score, 0) + "  " + (is_correct ? "correct" : "WRONG");
    const cv::Mat picture = DrawMatchPicture(*query, observation, *ref, reference_scale,
                                             totals.records[f].best, caption);
    char name[64];
    std::snprintf(name, sizeof(name), "/%s_%03d_to_%03d.jpg", is_correct ? "correct" : "wrong", f,
                  reference);
    cv::imwrite(dir + name, picture);
  }
  return Status::Ok();
}

// The run as far as it was fed, scored on the fed frames' revisits only: frames before `first`
// were fed by an earlier call, and their answers are not in this one.
Run ScoredRun(const Run& run, int first, int frames) {
  Run scored = FirstFrames(run, frames);
  if (first <= 0) return scored;
  for (auto it = scored.positives.begin(); it != scored.positives.end();) {
    it = it->first < first ? scored.positives.erase(it) : std::next(it);
  }
  for (int f = 0; f < first; ++f) {
    if (scored.is_revisit[f]) --scored.num_revisits;
    scored.is_revisit[f] = false;
  }
  return scored;
}

}  // namespace

StatusOr<EvalReport> EvaluateRun(const Run& run, const RecognizerOptions& options,
                                 const EvalOptions& eval) {
  std::string error;
  if (!options.Check(&error)) return Status::InvalidArgument(error);
  const int frames = eval.max_frames > 0 ? std::min<int>(eval.max_frames, run.frames.size())
                                         : static_cast<int>(run.frames.size());
  if (eval.first_frame > 0 && eval.db_path.empty()) {
    return Status::InvalidArgument(
        "a first frame above 0 continues a map file that an earlier run built: give --db");
  }
  if (eval.first_frame < 0 || eval.first_frame >= frames) {
    return Status::InvalidArgument("first frame " + std::to_string(eval.first_frame) +
                                   " is not below the last frame fed (" + std::to_string(frames) +
                                   ")");
  }
  if (!eval.out_dir.empty() && !MakeDirectories(eval.out_dir)) {
    return Status::IoError("cannot create output directory " + eval.out_dir);
  }
  StatusOr<std::unique_ptr<PlaceMap>> map = OpenMap(options, eval);
  if (!map.ok()) return map.status();
  StatusOr<std::unique_ptr<Segmenter>> segmenter = MakeSegmenter(options.analyzer);
  if (!segmenter.ok()) return segmenter.status();
  StatusOr<std::unique_ptr<ObjectClassLabeler>> labeler =
      ObjectClassLabeler::LoadIfEnabled(options.classes);
  if (!labeler.ok()) return labeler.status();
  Recognizer recognizer(options, map->get(), std::move(*segmenter), std::move(*labeler));

  EvalReport report;
  FeedTotals totals;
  totals.records.resize(frames);
  totals.frame_scale.assign(frames, 1.0);
  Timer run_timer;
  PLACEREC_RETURN_IF_ERROR(
      FeedFrames(run, eval, eval.first_frame, frames, run_timer, recognizer, &report, &totals));

  const Run scored = ScoredRun(run, eval.first_frame, frames);  // score only the frames that ran
  StatusOr<RunScore> score = ScoreAnswers(scored, report.answers);
  if (!score.ok()) return score.status();
  report.score = *score;
  const DecisionCounts decisions = CountDecisions(run, scored, report.answers, totals.records);
  report.summary = SummaryJson(run, frames - eval.first_frame, recognizer.options(), report,
                               decisions, totals, **map, recognizer, run_timer);
  report.summary["frame_width"] = eval.frame_width;  // 0: as recorded
  report.summary["first_frame"] = eval.first_frame;

  if (eval.out_dir.empty()) return report;
  PLACEREC_RETURN_IF_ERROR(WriteOutputs(run, eval.out_dir, report, totals));
  if (eval.pictures > 0) {
    PLACEREC_RETURN_IF_ERROR(
        WriteMatchPictures(run, scored, eval.first_frame, eval, report, totals, recognizer));
  }
  return report;
}

}  // namespace placerec
