// The server's bounded work queue: jobs are grouped in lanes (one per robot); a fixed pool of
// worker threads runs them, jobs of one lane strictly one at a time and in the order they were
// pushed, different lanes at once. The queue holds at most `capacity` jobs that have not started;
// a full queue refuses new jobs instead of growing, so the caller can answer "overloaded".
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
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

  // Starts `workers` threads that call `handler` for each job. `handler` must not throw.
  LaneWorkQueue(int workers, int capacity, Handler handler)
      : capacity_(capacity), handler_(std::move(handler)) {
    CHECK_GE(workers, 1);
    CHECK_GE(capacity, 1);
    for (int i = 0; i < workers; ++i) threads_.emplace_back([this] { WorkerLoop(); });
  }
  LaneWorkQueue(const LaneWorkQueue&) = delete;
  LaneWorkQueue& operator=(const LaneWorkQueue&) = delete;
  ~LaneWorkQueue() { Shutdown(); }

  // Queues *job behind the earlier jobs of `lane` and moves it out of *job. Returns false, leaving
  // *job untouched, when `capacity` jobs are already waiting or the queue is shut down.
  bool Push(const std::string& lane, Job* job) {
    {
      std::lock_guard lock(mutex_);
      if (stopping_ || depth_ >= capacity_) return false;
      Lane& l = lanes_[lane];
      l.jobs.push_back(std::move(*job));
      ++depth_;
      if (!l.busy && l.jobs.size() == 1) ready_.push_back(lane);
    }
    wake_.notify_one();
    return true;
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
    }
  }

  const int capacity_;
  Handler handler_;
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
