#include "client/fleet.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <thread>

#include "common/eval/stats.h"
#include "proto/channels.h"

namespace placerec {

bool FleetOptions::Check(std::string* error) const {
  if (robots < 1 || robots > 1000) {
    *error = "--robots must be in [1, 1000]";
    return false;
  }
  if (!(rate_hz > 0 && rate_hz <= 100)) {
    *error = "--rate must be in (0, 100] frames per second per robot";
    return false;
  }
  if (!(duration_s > 0) || !std::isfinite(duration_s) ||
      duration_s * rate_hz > kMaxFleetFramesPerRobot) {
    *error = "--duration must be > 0 seconds, and at most " +
             std::to_string(static_cast<int64_t>(kMaxFleetFramesPerRobot)) +
             " frames per robot at --rate";
    return false;
  }
  const std::string last_id = FleetRobotId(robot_prefix, std::max(0, robots - 1));
  if (std::string why; !IsValidWireRobotId(last_id, &why)) {
    *error = "--robot-prefix '" + robot_prefix + "' makes robot ids like '" + last_id +
             "' that the server refuses: " + why;
    return false;
  }
  if (!(query_share >= 0 && query_share <= 1)) {
    *error = "--query-share must be in [0, 1]";
    return false;
  }
  if (!(timeout_s > 0)) {
    *error = "the timeout must be > 0 seconds";
    return false;
  }
  return true;
}

std::string FleetRobotId(const std::string& prefix, int robot) {
  std::string number = std::to_string(robot);
  if (number.size() < 3) number.insert(0, 3 - number.size(), '0');
  return prefix + number;
}

StatusOr<FleetReport> RunFleet(PlacerecClient* client, const Run& run,
                               const FleetOptions& options) {
  std::string error;
  if (!options.Check(&error)) return Status::InvalidArgument(error);
  if (run.frames.empty()) return Status::InvalidArgument("the run has no frames");
  // Every image once, up front, so that reading files does not pace the robots.
  std::vector<EncodedImage> images;
  images.reserve(run.frames.size());
  for (const RunFrame& frame : run.frames) {
    StatusOr<EncodedImage> image = EncodeImageFile(frame.image);
    if (!image.ok()) return image.status();
    images.push_back(std::move(*image));
  }
  using Clock = std::chrono::steady_clock;
  const Clock::time_point start = Clock::now();
  const auto period = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(1.0 / options.rate_hz));
  const int per_robot = std::max(1, static_cast<int>(options.duration_s * options.rate_hz));
  // When each ok answer arrived, seconds after the start (its publication plus its latency).
  std::vector<double> ok_arrivals_s;

  std::mutex mutex;
  FleetReport report;
  std::atomic<int> published{0}, answered{0}, not_sent{0};
  std::atomic<bool> cut_short{false};  // a stop kept a frame from being sent
  std::vector<std::thread> threads;
  for (int r = 0; r < options.robots; ++r) {
    // One thread publishes on the robot's clock; another collects its answers in order.
    auto queue = std::make_shared<std::deque<PendingFrame>>();
    auto queue_mutex = std::make_shared<std::mutex>();
    auto queued = std::make_shared<std::condition_variable>();
    auto done = std::make_shared<bool>(false);
    const std::string robot = FleetRobotId(options.robot_prefix, r);
    threads.emplace_back([&, r, robot, queue, queue_mutex, queued, done] {
      const size_t offset = run.frames.size() * static_cast<size_t>(r) / options.robots;
      // Spread the robots' clocks over one period, as independent cameras are.
      const Clock::time_point first = start + period * r / options.robots;
      int64_t sequence = 0;
      const auto stopped = [&options] { return options.stop != nullptr && *options.stop; };
      for (int k = 0; k < per_robot; ++k) {
        // In slices, so that a stop is seen within a tenth of a second at any rate.
        const Clock::time_point due = first + period * k;
        while (!stopped() && Clock::now() < due) {
          std::this_thread::sleep_until(
              std::min(due, Clock::now() + std::chrono::milliseconds(100)));
        }
        if (stopped()) {
          cut_short = true;  // frame k and those after it are not sent
          break;
        }
        const size_t f = (offset + static_cast<size_t>(k)) % run.frames.size();
        OutgoingFrame frame;
        frame.robot = robot;
        // Query-only frames spread evenly: frame k is a query when the share's count rises.
        frame.insert = static_cast<int>((k + 1) * options.query_share) ==
                       static_cast<int>(k * options.query_share);
        frame.sequence = frame.insert ? sequence++ : k;
        frame.utime = run.frames[0].utime + static_cast<int64_t>(k * 1e6 / options.rate_hz);
        frame.image = images[f];
        StatusOr<PendingFrame> pending = client->Publish(frame);
        if (!pending.ok()) {
          // Offered but never on the network: counted, so that the figures say so.
          if (not_sent++ == 0) {
            std::fprintf(stderr, "fleet: a frame could not be sent: %s\n",
                         pending.status().message().c_str());
          }
          continue;
        }
        ++published;
        std::lock_guard lock(*queue_mutex);
        queue->push_back(*pending);
        queued->notify_one();
      }
      std::lock_guard lock(*queue_mutex);
      *done = true;
      queued->notify_one();
    });
    threads.emplace_back([&, queue, queue_mutex, queued, done] {
      while (true) {
        PendingFrame pending;
        {
          std::unique_lock lock(*queue_mutex);
          queued->wait(lock, [&] { return !queue->empty() || *done; });
          if (queue->empty()) return;
          pending = queue->front();
          queue->pop_front();
        }
        // The timeout runs from the frame's publication: waiting for the frames before it must
        // not add to it (with no server, N frames took N timeouts one after another, and late
        // answers counted as ok).
        const double waited = std::chrono::duration<double>(Clock::now() - pending.sent).count();
        FrameResult result = client->Wait(pending, std::max(0.0, options.timeout_s - waited));
        ++answered;
        std::lock_guard lock(mutex);
        if (result.ok()) {
          ok_arrivals_s.push_back(std::chrono::duration<double>(pending.sent - start).count() +
                                  result.latency_ms / 1000);
        }
        report.results.push_back(std::move(result));
      }
    });
  }
  std::atomic<bool> finished{false};
  std::thread progress([&] {
    while (options.progress && !finished) {
      std::fprintf(stderr, "\rfleet: %.0f s, %d frames sent, %d answered   ",
                   std::chrono::duration<double>(Clock::now() - start).count(), published.load(),
                   answered.load());
      std::this_thread::sleep_for(std::chrono::seconds(1));
    }
  });
  for (std::thread& t : threads) t.join();
  finished = true;
  progress.join();
  if (options.progress) std::fprintf(stderr, "\n");
  const double elapsed_s = std::chrono::duration<double>(Clock::now() - start).count();
  // Answered ok per second over the time up to the last ok answer: the wait for frames that
  // never get one (up to a whole timeout) is no time the server served in.
  const double serving_s =
      ok_arrivals_s.empty() ? 0.0 : *std::max_element(ok_arrivals_s.begin(), ok_arrivals_s.end());

  report.frames = published;
  std::map<std::string, int> by_code;
  std::vector<double> latency_ms;
  std::map<std::string, std::vector<double>> stage_ms;  // per pipeline stage, answered frames
  int ok = 0, overloaded = 0, timed_out = 0, loop_closures = 0;
  for (const FrameResult& r : report.results) {
    ++by_code[AnswerCodeName(r.code)];
    if (r.ok()) {
      ++ok;
      latency_ms.push_back(r.latency_ms);
      for (const auto& [stage, ms] : r.timings) stage_ms[stage].push_back(ms);
      if (r.loop_closure) ++loop_closures;
    }
    if (r.code == AnswerCode::kOverloaded) ++overloaded;
    if (r.code == AnswerCode::kTimeout) ++timed_out;
  }
  nlohmann::json stage_p50 = nlohmann::json::object();
  for (auto& [stage, ms] : stage_ms) stage_p50[stage] = Percentile(ms, 50);
  report.summary = {
      {"robots", options.robots},
      {"rate_hz_per_robot", options.rate_hz},
      {"offered_frames_per_second", options.robots * options.rate_hz},
      {"duration_s", options.duration_s},
      {"interrupted", cut_short.load()},
      {"elapsed_s", elapsed_s},
      {"query_share", options.query_share},
      {"frames", report.frames},
      {"not_sent", not_sent.load()},
      {"answers_by_status", by_code},
      {"ok", ok},
      {"overloaded", overloaded},
      {"timed_out", timed_out},
      {"loop_closures", loop_closures},
      {"answered_ok_per_second", serving_s > 0 ? ok / serving_s : 0.0},
      {"serving_s", serving_s},
      {"latency_ms",
       {{"p50", Percentile(latency_ms, 50)},
        {"p90", Percentile(latency_ms, 90)},
        {"p99", Percentile(latency_ms, 99)},
        {"max",
         latency_ms.empty() ? 0.0 : *std::max_element(latency_ms.begin(), latency_ms.end())}}},
      // The server's time per stage (median over answered frames, milliseconds); "insert" is
      // the map's commit, the part several servers on one map do one at a time.
      {"stage_ms_p50", stage_p50},
  };
  return report;
}

}  // namespace placerec
