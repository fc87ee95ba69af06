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

// report.results as "not sent" until an answer arrives.
void InitResults(const Run& run, int frames, FeedReport* report) {
  report->results.resize(frames);
  for (int f = 0; f < frames; ++f) {
    report->results[f].code = AnswerCode::kNotSent;
    report->results[f].message = "not sent";
    report->results[f].robot = run.frames[f].robot;
    report->results[f].sequence = f;
  }
}

// Senders: one for the whole run in order, or one per robot.
std::vector<std::vector<int>> Lanes(const Run& run, int frames, bool robots_concurrently) {
  std::vector<std::vector<int>> lanes;
  if (robots_concurrently) {
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
  return lanes;
}

// Sends the lanes' frames, each lane with at most `window` frames in flight, and records the
// answers in report->results. The senders and the client's answer callback share its state.
class Sender {
 public:
  Sender(PlacerecClient* client, const Run& run, const Run& scored, int frames,
         const FeedOptions& options, FeedReport* report)
      : client_(client),
        run_(run),
        scored_(scored),
        frames_(frames),
        options_(options),
        report_(report),
        progress_(static_cast<size_t>(frames), static_cast<size_t>(frames / 10)) {}

  // Feeds every lane (one thread per lane when there are several); returns the wall time in
  // seconds.
  double FeedAll(const std::vector<std::vector<int>>& lanes) {
    client_->SetAnswerCallback([this](const FrameResult& r) { OnAnswer(r); });
    if (lanes.size() == 1) {
      FeedLane(lanes[0]);
    } else {
      std::vector<std::thread> senders;
      for (const std::vector<int>& lane : lanes) {
        senders.emplace_back([this, &lane] { FeedLane(lane); });
      }
      for (std::thread& t : senders) t.join();
    }
    const double wall_s = wall_.ElapsedMs() / 1000.0;
    client_->SetAnswerCallback(nullptr);
    return wall_s;
  }

  int loop_closures() const { return loop_closures_; }
  bool cut_short() const { return cut_short_; }
  const Status& failure() const { return failure_; }

 private:
  using InFlight = std::deque<std::pair<int, PendingFrame>>;

  // One stdout line per loop closure as it arrives.
  void OnAnswer(const FrameResult& r) {
    if (!options_.print_loop_closures || !r.ok() || !r.loop_closure || r.matches.empty()) return;
    const int f = static_cast<int>(r.sequence);
    if (f < 0 || f >= frames_) return;
    const MatchedPlace& best = r.matches.front();
    const bool earlier = best.sequence >= 0 && best.sequence < f;
    const bool correct = earlier && run_.IsPositive(f, static_cast<int>(best.sequence));
    std::lock_guard lock(mutex_);
    if (options_.progress) progress_.Clear();
    std::printf(
        "loop closure: frame %d (%s) revisits frame %lld (%s), score %.0f, %d landmarks "
        "matched%s\n",
        f, r.robot.c_str(), static_cast<long long>(best.sequence), best.robot.c_str(), best.score,
        best.matched_landmarks,
        scored_.is_revisit[f] ? (correct ? "  [correct]" : "  [wrong place]")
                              : "  [not a revisit]");
    std::fflush(stdout);
  }

  void Record(int f, FrameResult result) {
    std::lock_guard lock(mutex_);
    ++answered_;
    if (result.ok() && result.loop_closure) ++loop_closures_;
    if (options_.progress) {
      const double elapsed = wall_.ElapsedMs() / 1000.0;
      progress_.Report(static_cast<size_t>(answered_),
                       "[%4d/%d] %5.1f%%  %s #%d %s  lm %3d  map %6lld lm  loops %d  %6.0f ms  "
                       "%.1f fps",
                       answered_, frames_, 100.0 * answered_ / frames_, result.robot.c_str(), f,
                       AnswerCodeName(result.code), result.landmarks,
                       static_cast<long long>(result.map_landmarks), loop_closures_,
                       result.latency_ms, elapsed > 0 ? answered_ / elapsed : 0.0);
    }
    report_->results[f] = std::move(result);
  }

  // Waits for the oldest frame in flight; a timeout sets `stop`.
  void Collect(InFlight* in_flight, bool* stop) {
    const auto [f, pending] = in_flight->front();
    in_flight->pop_front();
    const double waited =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - pending.sent).count();
    FrameResult result = client_->Wait(pending, std::max(0.0, options_.timeout_s - waited));
    if (result.code == AnswerCode::kTimeout) {
      result.message = "frame " + std::to_string(f) + ": " + result.message;
      *stop = true;
    }
    Record(f, std::move(result));
  }

  void FeedLane(const std::vector<int>& lane) {
    InFlight in_flight;
    bool stop = false;
    for (int f : lane) {
      while (!stop && static_cast<int>(in_flight.size()) >= options_.window) {
        Collect(&in_flight, &stop);
      }
      if (stop) break;
      if (options_.stop != nullptr && *options_.stop) {
        cut_short_ = true;  // frame f and those after it are not sent
        break;
      }
      StatusOr<EncodedImage> image = EncodeImageFile(run_.frames[f].image);
      if (!image.ok()) {
        std::lock_guard lock(mutex_);
        if (failure_.ok()) failure_ = image.status();
        stop = true;
        break;
      }
      OutgoingFrame frame;
      frame.robot = run_.frames[f].robot;
      frame.sequence = f;
      frame.utime = run_.frames[f].utime;
      frame.insert = true;
      frame.image = std::move(*image);
      StatusOr<PendingFrame> pending = client_->Publish(frame);
      if (!pending.ok()) {
        FrameResult result;
        result.code = AnswerCode::kNotSent;
        result.message = "frame " + std::to_string(f) + ": " + pending.status().message();
        result.robot = frame.robot;
        result.sequence = f;
        Record(f, std::move(result));
        continue;
      }
      in_flight.emplace_back(f, *pending);
    }
    while (!in_flight.empty()) Collect(&in_flight, &stop);
  }

  PlacerecClient* client_;
  const Run& run_;
  const Run& scored_;
  const int frames_;
  const FeedOptions& options_;
  FeedReport* report_;
  std::mutex mutex_;  // guards report_->results, the counters and the terminal
  int answered_ = 0;
  int loop_closures_ = 0;
  std::atomic<bool> cut_short_{false};  // a stop kept a frame from being sent
  Status failure_;
  ProgressLine progress_;
  Timer wall_;
};

// The answers' counts and times, gathered in frame order.
struct AnswerTally {
  std::vector<double> latency;
  std::vector<double> server;
  std::vector<double> queue;
  std::map<std::string, std::vector<double>> stage_ms;
  std::map<std::string, int> by_code;
  int later_references = 0;
  int tp = 0;
  int fp = 0;
  const FrameResult* last_map = nullptr;  // points into report->results
};

// Fills report->answers (answers.csv rows as placerec-eval writes them) and the ok / timed out /
// not sent / failed counts from report->results.
AnswerTally TallyAnswers(const Run& scored, int frames, FeedReport* report) {
  AnswerTally t;
  for (int f = 0; f < frames; ++f) {
    const FrameResult& r = report->results[f];
    ++t.by_code[AnswerCodeName(r.code)];
    Answer answer;
    answer.frame = f;
    if (r.ok()) {
      ++report->ok;
      t.latency.push_back(r.latency_ms);
      t.server.push_back(r.server_ms);
      t.queue.push_back(r.queue_ms);
      for (const auto& [stage, ms] : r.timings) t.stage_ms[stage].push_back(ms);
      if (t.last_map == nullptr || r.map_landmarks >= t.last_map->map_landmarks) t.last_map = &r;
      if (!r.matches.empty()) {
        const MatchedPlace& best = r.matches.front();
        if (best.sequence >= 0 && best.sequence < f) {
          answer.reference = static_cast<int>(best.sequence);
          answer.score = best.score;
          if (r.loop_closure) ++(scored.IsPositive(f, answer.reference) ? t.tp : t.fp);
        } else {
          ++t.later_references;  // only possible when robots are fed concurrently
        }
      }
    } else if (r.code == AnswerCode::kTimeout) {
      ++report->timed_out;
    } else if (r.code == AnswerCode::kNotSent) {
      ++report->not_sent;
    } else {
      ++report->failed;
    }
    report->answers.push_back(answer);
  }
  return t;
}

// What summary.json holds.
nlohmann::json SummaryJson(const Run& run, int frames, const FeedOptions& options,
                           const FeedReport& report, const AnswerTally& t, int loop_closures,
                           double wall_s, bool cut_short) {
  nlohmann::json s = ScoreSummary(run, frames, report.score);
  s["loop_closures"] = loop_closures;
  s["decision"] = DecisionSummary(t.tp, t.fp, report.score.revisit_frames);
  s["answers"] = t.by_code;
  s["later_references"] = t.later_references;
  s["latency"] = Spread(t.latency);
  s["server_time"] = Spread(t.server);
  s["queue_time"] = Spread(t.queue);
  nlohmann::json stages;
  for (const auto& [stage, values] : t.stage_ms) stages[stage] = Spread(values);
  s["stage_time"] = stages;
  s["wall_seconds"] = wall_s;
  s["frames_per_second"] = wall_s > 0 ? report.ok / wall_s : 0.0;
  s["window"] = options.window;
  s["interrupted"] = cut_short;
  s["robots_concurrently"] = options.robots_concurrently;
  if (t.last_map != nullptr) {
    s["map"] = {{"places", t.last_map->map_places},
                {"landmarks", t.last_map->map_landmarks},
                {"descriptors", t.last_map->map_descriptors}};
  }
  return s;
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
  InitResults(run, frames, &report);
  const std::vector<std::vector<int>> lanes = Lanes(run, frames, options.robots_concurrently);
  Sender sender(client, run, scored, frames, options, &report);
  const double wall_s = sender.FeedAll(lanes);
  if (!sender.failure().ok()) return sender.failure();

  const AnswerTally tally = TallyAnswers(scored, frames, &report);
  StatusOr<RunScore> score = ScoreAnswers(scored, report.answers);
  if (!score.ok()) return score.status();
  report.score = *score;
  report.summary = SummaryJson(run, frames, options, report, tally, sender.loop_closures(), wall_s,
                               sender.cut_short());
  return report;
}

Status WriteFeedReport(const std::string& out_dir, const FeedReport& report) {
  if (!MakeDirectories(out_dir)) return Status::IoError("cannot create or write in " + out_dir);
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
