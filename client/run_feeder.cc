#include "client/run_feeder.h"

#include <algorithm>
#include <cstdio>
#include <deque>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <thread>
#include <utility>

#include "common/eval/plots.h"
#include "common/eval/stats.h"
#include "common/util/paths.h"
#include "common/util/progress.h"
#include "common/util/timer.h"

namespace placerec {
namespace {

nlohmann::json Spread(const std::vector<double>& values) {
  return {{"median_ms", Median(values)},
          {"p90_ms", Percentile(values, 90)},
          {"max_ms", values.empty() ? 0.0 : *std::max_element(values.begin(), values.end())}};
}

}  // namespace

bool FeedOptions::Check(std::string* error) const {
  if (window < 1) {
    *error = "--window must be at least 1";
    return false;
  }
  if (max_frames < 0) {
    *error = "--max-frames must not be negative";
    return false;
  }
  if (!(timeout_s > 0)) {
    *error = "--timeout must be positive (seconds)";
    return false;
  }
  return true;
}

StatusOr<FeedReport> FeedRun(PlacerecClient* client, const Run& run, const FeedOptions& options) {
  std::string error;
  if (!options.Check(&error)) return Status::InvalidArgument(error);
  const int frames = options.max_frames > 0
                         ? std::min<int>(options.max_frames, static_cast<int>(run.frames.size()))
                         : static_cast<int>(run.frames.size());
  const Run scored = FirstFrames(run, frames);

  FeedReport report;
  report.results.resize(frames);
  for (int f = 0; f < frames; ++f) {
    report.results[f].code = AnswerCode::kNotSent;
    report.results[f].message = "not sent";
    report.results[f].robot = run.frames[f].robot;
    report.results[f].sequence = f;
  }

  // Senders: one for the whole run in order, or one per robot.
  std::vector<std::vector<int>> lanes;
  if (options.robots_concurrently) {
    std::map<std::string, int> lane_of;
    for (int f = 0; f < frames; ++f) {
      auto [it, added] = lane_of.emplace(run.frames[f].robot, static_cast<int>(lanes.size()));
      if (added) lanes.emplace_back();
      lanes[it->second].push_back(f);
    }
  } else {
    lanes.emplace_back();
    for (int f = 0; f < frames; ++f) lanes[0].push_back(f);
  }

  std::mutex mutex;  // guards report.results, the counters and the terminal
  int answered = 0;
  int loop_closures = 0;
  Status failure;
  ProgressLine progress(static_cast<size_t>(frames), static_cast<size_t>(frames / 10));
  Timer wall;

  client->SetAnswerCallback([&](const FrameResult& r) {
    if (!options.print_loop_closures || !r.ok() || !r.loop_closure || r.matches.empty()) return;
    const int f = static_cast<int>(r.sequence);
    if (f < 0 || f >= frames) return;
    const MatchedPlace& best = r.matches.front();
    const bool earlier = best.sequence >= 0 && best.sequence < f;
    const bool correct = earlier && run.IsPositive(f, static_cast<int>(best.sequence));
    std::lock_guard lock(mutex);
    if (options.progress) progress.Clear();
    std::printf(
        "loop closure: frame %d (%s) revisits frame %lld (%s), score %.0f, %d landmarks "
        "matched%s\n",
        f, r.robot.c_str(), static_cast<long long>(best.sequence), best.robot.c_str(), best.score,
        best.matched_landmarks,
        scored.is_revisit[f] ? (correct ? "  [correct]" : "  [wrong place]") : "  [not a revisit]");
    std::fflush(stdout);
  });

  auto record = [&](int f, FrameResult result) {
    std::lock_guard lock(mutex);
    ++answered;
    if (result.ok() && result.loop_closure) ++loop_closures;
    if (options.progress) {
      const double elapsed = wall.ElapsedMs() / 1000.0;
      progress.Report(static_cast<size_t>(answered),
                      "[%4d/%d] %5.1f%%  %s #%d %s  lm %3d  map %6lld lm  loops %d  %6.0f ms  "
                      "%.1f fps",
                      answered, frames, 100.0 * answered / frames, result.robot.c_str(), f,
                      AnswerCodeName(result.code), result.landmarks,
                      static_cast<long long>(result.map_landmarks), loop_closures,
                      result.latency_ms, elapsed > 0 ? answered / elapsed : 0.0);
    }
    report.results[f] = std::move(result);
  };

  auto feed = [&](const std::vector<int>& lane) {
    std::deque<std::pair<int, PendingFrame>> in_flight;
    bool stop = false;
    auto collect = [&] {
      const auto [f, pending] = in_flight.front();
      in_flight.pop_front();
      const double waited =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - pending.sent).count();
      FrameResult result = client->Wait(pending, std::max(0.0, options.timeout_s - waited));
      if (result.code == AnswerCode::kTimeout) {
        result.message = "frame " + std::to_string(f) + ": " + result.message;
        stop = true;
      }
      record(f, std::move(result));
    };
    for (int f : lane) {
      while (!stop && static_cast<int>(in_flight.size()) >= options.window) collect();
      if (stop) break;
      StatusOr<EncodedImage> image = EncodeImageFile(run.frames[f].image);
      if (!image.ok()) {
        std::lock_guard lock(mutex);
        if (failure.ok()) failure = image.status();
        stop = true;
        break;
      }
      OutgoingFrame frame;
      frame.robot = run.frames[f].robot;
      frame.sequence = f;
      frame.utime = run.frames[f].utime;
      frame.insert = true;
      frame.image = std::move(*image);
      StatusOr<PendingFrame> pending = client->Publish(frame);
      if (!pending.ok()) {
        FrameResult result;
        result.code = AnswerCode::kNotSent;
        result.message = "frame " + std::to_string(f) + ": " + pending.status().message();
        result.robot = frame.robot;
        result.sequence = f;
        record(f, std::move(result));
        continue;
      }
      in_flight.emplace_back(f, *pending);
    }
    while (!in_flight.empty()) collect();
  };

  if (lanes.size() == 1) {
    feed(lanes[0]);
  } else {
    std::vector<std::thread> senders;
    for (const std::vector<int>& lane : lanes) senders.emplace_back(feed, std::cref(lane));
    for (std::thread& t : senders) t.join();
  }
  const double wall_s = wall.ElapsedMs() / 1000.0;
  client->SetAnswerCallback(nullptr);
  if (!failure.ok()) return failure;

  // answers.csv rows as placerec-eval writes them.
  std::vector<double> latency;
  std::vector<double> server;
  std::vector<double> queue;
  std::map<std::string, std::vector<double>> stage_ms;
  std::map<std::string, int> by_code;
  int later_references = 0;
  int tp = 0;
  int fp = 0;
  const FrameResult* last_map = nullptr;
  for (int f = 0; f < frames; ++f) {
    const FrameResult& r = report.results[f];
    ++by_code[AnswerCodeName(r.code)];
    Answer answer;
    answer.frame = f;
    if (r.ok()) {
      ++report.ok;
      latency.push_back(r.latency_ms);
      server.push_back(r.server_ms);
      queue.push_back(r.queue_ms);
      for (const auto& [stage, ms] : r.timings) stage_ms[stage].push_back(ms);
      if (last_map == nullptr || r.map_landmarks >= last_map->map_landmarks) last_map = &r;
      if (!r.matches.empty()) {
        const MatchedPlace& best = r.matches.front();
        if (best.sequence >= 0 && best.sequence < f) {
          answer.reference = static_cast<int>(best.sequence);
          answer.score = best.score;
          if (r.loop_closure) ++(scored.IsPositive(f, answer.reference) ? tp : fp);
        } else {
          ++later_references;  // only possible when robots are fed concurrently
        }
      }
    } else if (r.code == AnswerCode::kTimeout) {
      ++report.timed_out;
    } else if (r.code == AnswerCode::kNotSent) {
      ++report.not_sent;
    } else {
      ++report.failed;
    }
    report.answers.push_back(answer);
  }
  StatusOr<RunScore> score = ScoreAnswers(scored, report.answers);
  if (!score.ok()) return score.status();
  report.score = *score;

  nlohmann::json& s = report.summary;
  s = ScoreSummary(run, frames, report.score);
  s["loop_closures"] = loop_closures;
  s["decision"] = DecisionSummary(tp, fp, report.score.revisit_frames);
  s["answers"] = by_code;
  s["later_references"] = later_references;
  s["latency"] = Spread(latency);
  s["server_time"] = Spread(server);
  s["queue_time"] = Spread(queue);
  nlohmann::json stages;
  for (const auto& [stage, values] : stage_ms) stages[stage] = Spread(values);
  s["stage_time"] = stages;
  s["wall_seconds"] = wall_s;
  s["frames_per_second"] = wall_s > 0 ? report.ok / wall_s : 0.0;
  s["window"] = options.window;
  s["robots_concurrently"] = options.robots_concurrently;
  if (last_map != nullptr) {
    s["map"] = {{"places", last_map->map_places},
                {"landmarks", last_map->map_landmarks},
                {"descriptors", last_map->map_descriptors}};
  }
  return report;
}

Status WriteFeedReport(const std::string& out_dir, const FeedReport& report) {
  if (!MakeDirectories(out_dir)) return Status::IoError("cannot create " + out_dir);
  PLACEREC_RETURN_IF_ERROR(WriteAnswers(out_dir + "/answers.csv", report.answers));
  {
    std::ofstream out(out_dir + "/summary.json");
    out << report.summary.dump(2) << "\n";
    if (!out) return Status::IoError("cannot write " + out_dir + "/summary.json");
  }
  PrCurve curve;
  char label[96];
  std::snprintf(label, sizeof(label), "placerec-server (R@100P %.2f, max F1 %.2f)",
                report.score.recall_at_100_precision, report.score.max_f1);
  curve.label = label;
  curve.score = report.score;
  const std::string title = report.summary.value("run", std::string("run"));
  return WritePrCurvePng(out_dir + "/pr_curve.png", title + ": precision-recall", {curve});
}

}  // namespace placerec
