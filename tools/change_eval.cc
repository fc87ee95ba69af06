#include "tools/change_eval.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/eval/alarms.h"
#include "common/eval/stats.h"
#include "common/image/image.h"
#include "common/storage/sqlite_store.h"
#include "common/util/paths.h"
#include "common/util/progress.h"
#include "common/util/timer.h"
#include "tools/change_tally.h"

namespace placerec {
namespace {

// A double as text that reads back as the same value (whether a case is a hit is decided on it).
std::string ExactText(double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.17g", value);
  return text;
}

// Where a case's true box lay for the detector: the share of it inside the compared view, and
// its mean difference there as a multiple of the frame's threshold (the box holds background
// too, so even a found object's value lies below 1; compare a miss's value with the hits' of
// the same run: far below them it differed too little, among them it was dropped by a rule or
// found with the wrong box).
struct TruthInView {
  double share = 0;
  double difference = 0;
};

TruthInView TruthSeen(const ChangeReport& report, const cv::Rect& truth, double image_scale,
                      const cv::Size& processed) {
  TruthInView seen;
  if (truth.empty() || report.shared.empty() || report.difference.empty() ||
      report.threshold <= 0 || processed.width <= 0) {
    return seen;
  }
  // Input pixels -> processed pixels -> the thumbnail's.
  const double to_thumb = image_scale * report.shared.cols / processed.width;
  const cv::Rect box = cv::Rect(cv::Point(static_cast<int>(truth.x * to_thumb),
                                          static_cast<int>(truth.y * to_thumb)),
                                cv::Point(static_cast<int>(std::ceil(truth.br().x * to_thumb)),
                                          static_cast<int>(std::ceil(truth.br().y * to_thumb)))) &
                       cv::Rect(0, 0, report.shared.cols, report.shared.rows);
  if (box.area() <= 0) return seen;
  const cv::Mat inside = report.shared(box) != 0;
  const int count = cv::countNonZero(inside);
  seen.share = static_cast<double>(count) / box.area();
  if (count > 0) seen.difference = cv::mean(report.difference(box), inside)[0] / report.threshold;
  return seen;
}

// Frame with the true box (green), the changes found (red / yellow) and the stored thumbnail.
cv::Mat Picture(const cv::Mat& frame, const cv::Size& processed, double image_scale,
                const cv::Rect& truth, const ChangeReport& report) {
  const int width = 480;
  const double s = static_cast<double>(width) / frame.cols;
  cv::Mat left;
  cv::resize(frame, left, cv::Size(width, static_cast<int>(frame.rows * s)), 0, 0, cv::INTER_AREA);
  if (!truth.empty()) {
    cv::rectangle(left, cv::Rect(cv::Point(truth.tl() * s), cv::Point(truth.br() * s)),
                  cv::Scalar(0, 220, 0), 2);
  }
  const double to_left = s / image_scale;  // processed pixels -> picture
  for (const SceneChange& change : report.changes) {
    const cv::Rect box(cv::Point(change.box.tl() * to_left), cv::Point(change.box.br() * to_left));
    cv::rectangle(left, box,
                  change.kind == SceneChange::Kind::kAppeared ? cv::Scalar(0, 0, 255)
                                                              : cv::Scalar(0, 220, 255),
                  2);
  }
  (void)processed;
  cv::Mat right(left.rows, 240, CV_8UC3, cv::Scalar(40, 40, 40));
  if (!report.place_picture.empty()) {
    cv::Mat place = cv::imdecode(report.place_picture, cv::IMREAD_COLOR);
    if (!place.empty()) {
      cv::resize(place, place, cv::Size(240, std::min(left.rows, 240 * place.rows / place.cols)));
      place.copyTo(right(cv::Rect(0, 0, place.cols, place.rows)));
    }
  }
  if (!report.difference.empty()) {
    cv::Mat difference;
    report.difference.convertTo(difference, CV_8U, 4.0);  // 64 Lab units is white
    cv::cvtColor(difference, difference, cv::COLOR_GRAY2BGR);
    cv::resize(difference, difference,
               cv::Size(240, std::min(left.rows - 2 - right.rows / 2,
                                      240 * difference.rows / difference.cols)));
    const int top = left.rows - difference.rows;
    if (top >= 0) difference.copyTo(right(cv::Rect(0, top, difference.cols, difference.rows)));
  }
  cv::Mat both;
  cv::hconcat(left, right, both);
  return both;
}

}  // namespace

StatusOr<nlohmann::json> EvaluateChanges(const Run& run, const RecognizerOptions& options,
                                         const ChangeEvalOptions& eval) {
  std::string error;
  if (!options.Check(&error)) return Status::InvalidArgument(error);
  if (!options.change.enabled) {
    return Status::InvalidArgument("change detection is off (--change-detection false)");
  }
  if (!(eval.colour_shift >= 0.0 && eval.colour_shift <= 1.0)) {
    return Status::InvalidArgument("--paste-colour-shift must be in [0, 1]");
  }
  if (eval.out_dir.empty() || !MakeDirectories(eval.out_dir + "/pictures")) {
    return Status::IoError("cannot create or write in " + eval.out_dir + "/pictures");
  }
  // The objects to paste.
  std::vector<CutObject> objects;
  for (const std::string& dataset : eval.object_datasets) {
    StatusOr<std::vector<CutObject>> cut = CutTestObjects(dataset, eval.cut);
    if (!cut.ok()) return cut.status();
    for (CutObject& object : *cut) objects.push_back(std::move(object));
  }
  if (objects.empty()) return Status::NotFound("no objects to paste in the labelled datasets");

  SqliteStoreOptions store_options;
  StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(":memory:", store_options);
  if (!store.ok()) return store.status();
  StatusOr<std::unique_ptr<PlaceMap>> map =
      PlaceMap::Open(std::move(*store), EffectiveOptions(options).index);
  if (!map.ok()) return map.status();
  StatusOr<std::unique_ptr<Segmenter>> segmenter = MakeSegmenter(options.analyzer);
  if (!segmenter.ok()) return segmenter.status();
  StatusOr<std::unique_ptr<ObjectClassLabeler>> labeler =
      ObjectClassLabeler::LoadIfEnabled(options.classes);
  if (!labeler.ok()) return labeler.status();
  Recognizer recognizer(options, map->get(), std::move(*segmenter), std::move(*labeler));

  std::mt19937_64 rng(eval.seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const int frames = eval.max_frames > 0 ? std::min<int>(eval.max_frames, run.frames.size())
                                         : static_cast<int>(run.frames.size());
  ChangeTally pasted, removed;
  ClassTally classes;  // of the pasted objects found
  int unchanged = 0, unchanged_checked = 0, false_alarms = 0, loop_closures = 0;
  int pastes_not_made = 0, removals_not_made = 0;  // planned changes that could not be made
  int revisits = 0;
  std::vector<double> change_ms, sift_ms;
  int pictures_hit = 0, pictures_miss = 0, pictures_false = 0;
  ProgressLine progress(static_cast<size_t>(frames), 50);
  // The changed run, to replay live (ChangeEvalOptions::write_run_dir).
  Run changed_run = FirstFrames(run, frames);
  changed_run.name = run.name + "_changed";
  std::ofstream changes_csv;
  if (!eval.write_run_dir.empty()) {
    if (!MakeDirectories(eval.write_run_dir + "/runs") ||
        !MakeDirectories(eval.write_run_dir + "/images")) {
      return Status::IoError("cannot create or write in " + eval.write_run_dir +
                             "/runs and /images");
    }
    for (RunFrame& f : changed_run.frames) {
      f.image = std::filesystem::absolute(f.image).lexically_normal().string();
    }
    changes_csv.open(eval.write_run_dir + "/runs/" + changed_run.name + ".changes.csv");
    changes_csv << ChangeCaseHeader() << '\n';
    if (!changes_csv) {
      return Status::IoError("cannot write " + eval.write_run_dir + "/runs/" + changed_run.name +
                             ".changes.csv");
    }
  }
  std::ofstream cases(eval.out_dir + "/revisits.csv");
  cases << "frame,case,truth_x,truth_y,truth_w,truth_h,loop_closure,best_inliers,compared,why_not,"
           "changes,best_iou,boxes,truth_in_view,truth_difference,threshold,dropped_by,dropped,"
           "pasted_class,found_class,found_class_confidence,area_share\n";
  for (int i = 0; i < frames; ++i) {
    const RunFrame& frame = run.frames[i];
    StatusOr<cv::Mat> image = ReadImageFile(frame.image);
    if (!image.ok()) return image.status();
    const FrameObservation observation = recognizer.Analyze(*image);
    FrameRequest request{frame.robot, frame.frame, frame.utime, true};
    if (run.is_revisit[i]) {
      const int k = revisits++;
      const bool changed = k % 2 == 1;
      const bool removal = changed && eval.removal_every > 0 &&
                           (k / 2) % eval.removal_every == eval.removal_every - 1;
      cv::Mat query = *image;
      cv::Rect truth;
      std::string what;
      std::string pasted_class;  // the pasted object's class ("" for the other cases)
      double area_share = 0;     // of the frame, the change covers
      if (changed && !removal) {
        query = image->clone();
        const CutObject& object = objects[static_cast<size_t>(unit(rng) * objects.size())];
        const double share =
            eval.min_area_share * std::pow(eval.max_area_share / eval.min_area_share, unit(rng));
        const double x = unit(rng), y = unit(rng);
        truth = PasteObject(object, share, x, y, eval.colour_shift, &query, &area_share);
        what = object.class_name + " from " + object.source;
        pasted_class = object.class_name;
      } else if (removal) {
        // Paint over a stored landmark where the frame shows it (a landmark gone): of the frame's
        // objects of 1-10 % of the frame holding at least 3 verified points of the place the
        // unchanged frame is matched to (its counterparts of the place's landmarks), the one
        // holding the most.
        FrameRequest plain_query = request;
        plain_query.insert = false;
        const RecognitionResult plain = recognizer.Recognize(plain_query, observation);
        const double frame_area = static_cast<double>(observation.processed_size.area());
        const SceneObject* chosen = nullptr;
        int chosen_points = 0;
        if (!plain.matches.empty() && plain.matches.front().inliers > 0) {
          for (const SceneObject& object : observation.objects) {
            const double share = object.box.area() / frame_area;
            if (share < eval.min_area_share || share > eval.max_area_share) continue;
            int points = 0;
            for (const auto& [at_frame, at_place] : plain.matches.front().point_pairs) {
              points += object.box.contains(cv::Point(at_frame)) ? 1 : 0;
            }
            if (points >= 3 && points > chosen_points) {
              chosen = &object;
              chosen_points = points;
            }
          }
        }
        if (chosen != nullptr) {
          query = image->clone();
          const double to_frame = 1.0 / observation.scale;
          const cv::Rect box(cv::Point(chosen->box.tl() * to_frame),
                             cv::Point(chosen->box.br() * to_frame));
          truth = PaintOver(box, &query);
          area_share = static_cast<double>(truth.area()) / query.total();
          what = "painted over";
        }
      }
      ChangeCase written_case;
      written_case.frame = frame.frame;
      written_case.robot = frame.robot;
      written_case.utime = frame.utime;
      written_case.kind = !truth.empty()
                              ? (removal ? ChangeCase::Kind::kRemoved : ChangeCase::Kind::kPasted)
                          : changed ? ChangeCase::Kind::kNotMade
                                    : ChangeCase::Kind::kUnchanged;
      written_case.truth = truth;
      written_case.frame_size = query.size();
      written_case.object_class = pasted_class;
      written_case.area_share = area_share;
      if (changes_csv.is_open()) {
        if (!truth.empty()) {
          const std::string written =
              "images/" + run.name + "_" + std::to_string(frame.frame) + ".jpg";
          if (!cv::imwrite(eval.write_run_dir + "/" + written, query,
                           {cv::IMWRITE_JPEG_QUALITY, 95})) {
            return Status::IoError("cannot write " + eval.write_run_dir + "/" + written);
          }
          changed_run.frames[i].image = written;
        }
        changes_csv << ChangeCaseLine(written_case) << '\n';
      }
      const FrameObservation asked = truth.empty() ? observation : recognizer.Analyze(query);
      FrameRequest as_query = request;
      as_query.insert = false;
      const RecognitionResult answer = recognizer.Recognize(as_query, asked);
      for (const auto& [stage, ms] : answer.timings) {
        if (stage == "change") change_ms.push_back(ms);
        if (stage == "sift") sift_ms.push_back(ms);
      }
      loop_closures += answer.loop_closure ? 1 : 0;
      const ChangeReport& report = answer.change;
      const cv::Size processed = asked.processed_size;
      std::string kind;
      if (written_case.kind == ChangeCase::Kind::kNotMade) {
        ++(removal ? removals_not_made : pastes_not_made);
      } else if (truth.empty()) {
        ++unchanged;
        unchanged_checked += report.checked ? 1 : 0;
        if (!report.changes.empty()) {
          ++false_alarms;
          kind = pictures_false++ < eval.pictures ? "false_alarm" : "";
        }
      } else {
        ChangeTally& tally = removal ? removed : pasted;
        tally.checked += report.checked ? 1 : 0;
        double best = 0;
        for (const SceneChange& change : report.changes) {
          const double to_frame = 1.0 / asked.scale;
          const cv::Rect box(cv::Point(change.box.tl() * to_frame),
                             cv::Point(change.box.br() * to_frame));
          best = std::max(best, BoxIoU(box, truth));
        }
        tally.Add(written_case.AreaShare(), best >= eval.min_iou, best);
        if (best >= eval.min_iou) {
          kind = pictures_hit++ < eval.pictures ? "hit" : "";
        } else {
          // Pictures of the misses that were compared: those say why the detector missed.
          if (report.checked) kind = pictures_miss++ < eval.pictures ? "miss" : "";
        }
      }
      {
        const char* what_case = ChangeCaseKindName(written_case.kind);
        double best = 0;
        std::string boxes;
        const SceneChange* found = nullptr;  // the change over the truth (best IoU), if a hit
        for (const SceneChange& change : report.changes) {
          const double to_frame = 1.0 / asked.scale;
          const cv::Rect box(cv::Point(change.box.tl() * to_frame),
                             cv::Point(change.box.br() * to_frame));
          const double iou = BoxIoU(box, truth);
          if (iou > best) {
            best = iou;
            if (iou >= eval.min_iou) found = &change;
          }
          boxes += (boxes.empty() ? "" : ";") + std::to_string(box.x) + " " +
                   std::to_string(box.y) + " " + std::to_string(box.width) + " " +
                   std::to_string(box.height) + " " + std::to_string(change.confidence);
        }
        const TruthInView in_view = TruthSeen(report, truth, asked.scale, processed);
        // The rule that dropped the region overlapping the truth most (IoU >= 0.1), if any.
        std::string dropped_by;
        double dropped_iou = 0.1;
        std::map<std::string, int> dropped_rules;  // every dropped region, by rule
        for (const DroppedRegion& region : report.dropped) {
          ++dropped_rules[region.rule];
          if (best >= eval.min_iou) continue;  // found: no rule dropped it
          const double to_frame = 1.0 / asked.scale;
          const cv::Rect box(cv::Point(region.box.tl() * to_frame),
                             cv::Point(region.box.br() * to_frame));
          const double overlap = BoxIoU(box, truth);
          if (overlap >= dropped_iou) {
            dropped_iou = overlap;
            dropped_by = region.rule;
          }
        }
        cases << frame.frame << ',' << what_case << ',' << truth.x << ',' << truth.y << ','
              << truth.width << ',' << truth.height << ',' << answer.loop_closure << ','
              << (answer.matches.empty() ? -1 : answer.matches.front().inliers) << ','
              << report.checked << ",\"" << report.why_not << "\"," << report.changes.size() << ','
              << ExactText(best) << ",\"" << boxes << "\"," << in_view.share << ','
              << in_view.difference << ',' << report.threshold << ',' << dropped_by << ",\"";
        for (const auto& [rule, count] : dropped_rules) {
          cases << (rule == dropped_rules.begin()->first ? "" : " ") << rule << ':' << count;
        }
        cases << "\"," << pasted_class << ',' << (found ? found->object_class : "") << ','
              << (found ? found->class_confidence : 0.f) << ',' << written_case.area_share << '\n';
        if (found != nullptr && !removal) {
          classes.Add(pasted_class, found->object_class, found->class_confidence);
        }
      }
      if (!kind.empty()) {
        char name[256];
        std::snprintf(name, sizeof(name), "%s/pictures/%s_%04d.png", eval.out_dir.c_str(),
                      kind.c_str(), frame.frame);
        cv::imwrite(name, Picture(query, processed, asked.scale, truth, report));
      }
      (void)what;
    }
    const RecognitionResult inserted = recognizer.Recognize(request, observation);
    if (!inserted.status.ok()) return inserted.status;
    if (eval.progress && progress.Due(static_cast<size_t>(i + 1))) {
      std::fprintf(stderr, "\r%d/%d frames, %d revisits", i + 1, frames, revisits);
    }
  }
  if (eval.progress) std::fprintf(stderr, "\n");
  if (changes_csv.is_open()) {
    changes_csv.close();
    if (!changes_csv) return Status::IoError("cannot write the changes of " + changed_run.name);
    const Status written = WriteRun(changed_run, eval.write_run_dir + "/runs/" + changed_run.name);
    if (!written.ok()) return written;
  }

  nlohmann::json j;
  j["dataset"] = run.dataset_dir.substr(run.dataset_dir.find_last_of('/') + 1);
  j["run"] = run.name;
  j["frames"] = frames;
  j["revisits"] = revisits;
  j["revisit_loop_closures"] = loop_closures;
  j["seed"] = eval.seed;
  j["paste_colour_shift"] = eval.colour_shift;
  j["change_options"] = {{"sensitivity", options.change.sensitivity},
                         {"threshold_lab", options.change.Threshold()},
                         {"min_area", options.change.min_area},
                         {"min_inliers_without_loop", options.change.min_inliers_without_loop},
                         {"segment_difference", options.change.segment_difference}};
  j["appeared"] = ChangeTallyJson(pasted);
  j["removed"] = ChangeTallyJson(removed);
  j["appeared_classes"] = ClassTallyJson(classes);
  j["detection_recall"] = j["appeared"]["detection_recall"];
  j["detection_recall_2pct"] = j["appeared"]["detection_recall_2pct"];
  j["localisation_iou"] = j["appeared"]["localisation_iou_median"];
  j["unchanged"] = unchanged;
  j["unchanged_compared"] = unchanged_checked;
  j["false_alarms"] = false_alarms;
  j["false_alarm_rate"] = ShareOf(false_alarms, unchanged);
  // Only a compared revisit can raise an alarm: the rate among those is the detector's own.
  j["false_alarm_rate_compared"] = ShareOf(false_alarms, unchanged_checked);
  j["pastes_not_made"] = pastes_not_made;
  j["removals_not_made"] = removals_not_made;
  j["change_ms_median"] = change_ms.empty() ? 0.0 : Percentile(change_ms, 50);
  j["sift_ms_median"] = sift_ms.empty() ? 0.0 : Percentile(sift_ms, 50);
  std::ofstream(eval.out_dir + "/change.json") << j.dump(2) << "\n";
  return j;
}

}  // namespace placerec
