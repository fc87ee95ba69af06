// The server's bounded work queue: jobs are grouped in lanes (one per robot); a fixed pool of
// worker threads runs them, jobs of one lane strictly one at a time and in the order they were
// pushed, different lanes at once. The queue holds at most `capacity` jobs that have not started;
// a full queue refuses new jobs instead of growing, so the caller can answer "overloaded". Lanes
// share a full queue fairly: a lane may fill the queue while no other lane waits, but a job of a
// lane holding fewer waiting jobs than the largest lane (by two or more) pushes out that lane's
// newest waiting job, which the caller answers instead. So one robot's flood cannot keep another
// robot's frames out; at worst each of k waiting robots keeps about capacity / k frames.
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <unordered_map>
#include <utility>
#include <vector>

#include <glog/logging.h>

namespace placerec {

template <typename Job>
class LaneWorkQueue {
 public:
  using Handler = std::function<void(Job&)>;

  // Starts `workers` threads that call `handler` for each job. `handler` must not throw. `idle`
  // (may be empty, must not throw) runs on the worker that finished a job when no other job
  // runs or waits: once per burst of work. A job pushed meanwhile may start on another worker
  // (or wait for this one), so `idle` must be quick and must not assume the queue stays empty.
  LaneWorkQueue(int workers, int capacity, Handler handler, std::function<void()> idle = {})
      : capacity_(capacity), handler_(std::move(handler)), idle_(std::move(idle)) {
    CHECK_GE(workers, 1);
    CHECK_GE(capacity, 1);
    for (int i = 0; i < workers; ++i) threads_.emplace_back([this] { WorkerLoop(); });
  }
  LaneWorkQueue(const LaneWorkQueue&) = delete;
  LaneWorkQueue& operator=(const LaneWorkQueue&) = delete;
  ~LaneWorkQueue() { Shutdown(); }

  struct PushResult {
    bool queued = false;
    bool stopped = false;  // refused because the queue is shut down
    int waiting = 0;       // jobs waiting before the push
    int lane_waiting = 0;  // of them, the pushing lane's
    // Set when a full queue made room by pushing out the newest waiting job of the lane that
    // held the most: that job (never started) and its lane, with the lane's waiting jobs before.
    std::optional<Job> evicted;
    std::string evicted_lane;
    int evicted_lane_waiting = 0;
  };

  // Queues *job behind the earlier jobs of `lane` and moves it out of *job. When `capacity` jobs
  // are already waiting, the job is queued only if some other lane holds at least two more
  // waiting jobs than `lane`: that lane's newest waiting job is moved into the result's
  // `evicted`. Otherwise, or when the queue is shut down, `queued` is false and *job untouched.
  PushResult Push(const std::string& lane, Job* job) {
    PushResult result;
    {
      std::lock_guard lock(mutex_);
      result.waiting = depth_;
      const auto own = lanes_.find(lane);
      result.lane_waiting = own == lanes_.end() ? 0 : static_cast<int>(own->second.jobs.size());
      if (stopping_) {
        result.stopped = true;
        return result;
      }
      if (depth_ >= capacity_) {
        auto largest = lanes_.end();
        for (auto it = lanes_.begin(); it != lanes_.end(); ++it) {
          if (largest == lanes_.end() || it->second.jobs.size() > largest->second.jobs.size()) {
            largest = it;
          }
        }
        if (largest == lanes_.end() ||
            static_cast<int>(largest->second.jobs.size()) < result.lane_waiting + 2) {
          return result;
        }
        result.evicted_lane = largest->first;
        result.evicted_lane_waiting = static_cast<int>(largest->second.jobs.size());
        result.evicted.emplace(std::move(largest->second.jobs.back()));
        largest->second.jobs.pop_back();
        --depth_;
        // The lane keeps at least one waiting job (it held two more than `lane`), so it stays in
        // ready_ or busy as it was.
      }
      Lane& l = lanes_[lane];
      l.jobs.push_back(std::move(*job));
      ++depth_;
      if (!l.busy && l.jobs.size() == 1) ready_.push_back(lane);
      result.queued = true;
    }
    wake_.notify_one();
    return result;
  }

  // Stops taking jobs, lets the running ones finish, joins the workers and returns the jobs that
  // never started, each lane's in order. Safe to call twice (the second call returns nothing).
  std::vector<Job> Shutdown() {
    std::vector<Job> pending;
    {
      std::lock_guard lock(mutex_);
      stopping_ = true;
      for (auto& [name, lane] : lanes_) {
        for (Job& job : lane.jobs) pending.push_back(std::move(job));
        lane.jobs.clear();
      }
      ready_.clear();
      depth_ = 0;
    }
    wake_.notify_all();
    for (std::thread& t : threads_) {
      if (t.joinable()) t.join();
    }
    return pending;
  }

  // Jobs waiting for a worker.
  int depth() const {
    std::lock_guard lock(mutex_);
    return depth_;
  }
  // Jobs being run right now.
  int running() const {
    std::lock_guard lock(mutex_);
    return running_;
  }
  int capacity() const { return capacity_; }
  int workers() const { return static_cast<int>(threads_.size()); }

 private:
  struct Lane {
    std::deque<Job> jobs;
    bool busy = false;  // a worker runs one of its jobs
  };

  void WorkerLoop() {
    std::unique_lock lock(mutex_);
    for (;;) {
      wake_.wait(lock, [this] { return stopping_ || !ready_.empty(); });
      if (stopping_) return;
      const std::string name = std::move(ready_.front());
      ready_.pop_front();
      Lane& lane = lanes_[name];
      Job job = std::move(lane.jobs.front());
      lane.jobs.pop_front();
      lane.busy = true;
      --depth_;
      ++running_;
      lock.unlock();
      handler_(job);
      lock.lock();
      --running_;
      auto it = lanes_.find(name);
      if (it != lanes_.end()) {
        it->second.busy = false;
        if (!it->second.jobs.empty() && !stopping_) {
          ready_.push_back(name);
          wake_.notify_one();
        } else if (it->second.jobs.empty()) {
          lanes_.erase(it);
        }
      }
      if (idle_ && running_ == 0 && depth_ == 0 && !stopping_) {
        lock.unlock();
        idle_();
        lock.lock();
      }
    }
  }

  const int capacity_;
  Handler handler_;
  std::function<void()> idle_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::unordered_map<std::string, Lane> lanes_;
  std::deque<std::string> ready_;  // lanes with jobs and no running job, oldest first
  int depth_ = 0;
  int running_ = 0;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace placerec
