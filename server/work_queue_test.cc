#include "server/work_queue.h"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace placerec {
namespace {

struct TestJob {
  std::string lane;
  int index = 0;
};

// Blocks handlers until opened.
class Gate {
 public:
  void Open() {
    std::lock_guard lock(mutex_);
    open_ = true;
    cv_.notify_all();
  }
  void Wait() {
    std::unique_lock lock(mutex_);
    cv_.wait(lock, [this] { return open_; });
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  bool open_ = false;
};

// Waits are on events, never on a fixed time, so that the tests neither flake on a loaded
// machine nor wait longer than they must. This bound only turns a hang into a failure.
constexpr auto kTimeout = std::chrono::seconds(30);

// Counts events (a handler started, a job finished) and wakes whoever waits for a count.
class Counter {
 public:
  void Increment() {
    std::lock_guard lock(mutex_);
    ++count_;
    cv_.notify_all();
  }
  int value() {
    std::lock_guard lock(mutex_);
    return count_;
  }
  // Whether the count reached `n` within kTimeout.
  ::testing::AssertionResult WaitFor(int n) {
    std::unique_lock lock(mutex_);
    if (cv_.wait_for(lock, kTimeout, [&] { return count_ >= n; })) {
      return ::testing::AssertionSuccess();
    }
    return ::testing::AssertionFailure()
           << "waited " << kTimeout.count() << " s for " << n << " events, saw " << count_;
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  int count_ = 0;
};

// Polls `done` (state the queue offers no event for) until it holds or kTimeout passes.
template <typename Predicate>
::testing::AssertionResult Eventually(Predicate done, const std::string& what) {
  const auto deadline = std::chrono::steady_clock::now() + kTimeout;
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) {
      return ::testing::AssertionFailure()
             << "waited " << kTimeout.count() << " s for " << what << "; it never happened";
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return ::testing::AssertionSuccess();
}

TEST(LaneWorkQueueTest, EachLaneInOrderAndNeverTwiceAtOnce) {
  std::mutex mutex;
  std::map<std::string, std::vector<int>> order;
  std::map<std::string, int> running;
  bool overlap = false;
  std::atomic<int> max_running{0};
  std::atomic<int> now_running{0};
  // The first job of each lane waits until all three run (three workers, three lanes), so that
  // "lanes ran at once" does not depend on timing; a queue that ran lanes one after the other
  // would let the wait time out and max_running stay 1.
  Counter first_jobs;
  Counter finished;
  {
    LaneWorkQueue<TestJob> queue(3, 1000, [&](TestJob& job) {
      {
        std::lock_guard lock(mutex);
        if (running[job.lane]++ > 0) overlap = true;
      }
      const int n = ++now_running;
      int seen = max_running.load();
      while (n > seen && !max_running.compare_exchange_weak(seen, n)) {
      }
      if (job.index == 0) {
        first_jobs.Increment();
        EXPECT_TRUE(first_jobs.WaitFor(3)) << "the first jobs of the three lanes never ran at once";
      }
      std::this_thread::yield();
      --now_running;
      {
        std::lock_guard lock(mutex);
        --running[job.lane];
        order[job.lane].push_back(job.index);
      }
      finished.Increment();
    });
    for (int i = 0; i < 60; ++i) {
      for (const char* lane : {"a", "b", "c"}) {
        TestJob job{lane, i};
        ASSERT_TRUE(queue.Push(lane, &job).queued);
      }
    }
    ASSERT_TRUE(finished.WaitFor(180));
  }
  EXPECT_FALSE(overlap);
  EXPECT_GT(max_running.load(), 1);  // lanes ran at once
  for (const char* lane : {"a", "b", "c"}) {
    ASSERT_EQ(order[lane].size(), 60u);
    for (int i = 0; i < 60; ++i) EXPECT_EQ(order[lane][i], i) << lane;
  }
}

TEST(LaneWorkQueueTest, RefusesJobsBeyondCapacity) {
  Gate gate;
  Counter started;
  Counter done;
  LaneWorkQueue<TestJob> queue(2, 3, [&](TestJob&) {
    started.Increment();
    gate.Wait();
    done.Increment();
  });
  TestJob a{"a", 0};
  TestJob b{"b", 0};
  ASSERT_TRUE(queue.Push("a", &a).queued);
  ASSERT_TRUE(queue.Push("b", &b).queued);
  ASSERT_TRUE(started.WaitFor(2));
  EXPECT_EQ(queue.running(), 2);
  // Lanes a, b and c hold one waiting job each: none holds two more than d's none, so d is
  // refused, and so is a.
  for (const char* lane : {"a", "b", "c"}) {
    TestJob job{lane, 1};
    ASSERT_TRUE(queue.Push(lane, &job).queued);
  }
  EXPECT_EQ(queue.depth(), 3);
  TestJob refused{"d", 9};
  const auto full = queue.Push("d", &refused);
  EXPECT_FALSE(full.queued);
  EXPECT_FALSE(full.stopped);
  EXPECT_FALSE(full.evicted.has_value());
  EXPECT_EQ(full.waiting, 3);
  EXPECT_EQ(full.lane_waiting, 0);
  EXPECT_EQ(refused.lane, "d");  // left untouched
  EXPECT_EQ(refused.index, 9);
  TestJob a2{"a", 2};
  const auto own = queue.Push("a", &a2);
  EXPECT_FALSE(own.queued);
  EXPECT_EQ(own.lane_waiting, 1);
  gate.Open();
  ASSERT_TRUE(done.WaitFor(5));
  EXPECT_EQ(queue.depth(), 0);
  TestJob again{"d", 10};
  EXPECT_TRUE(queue.Push("d", &again).queued);
}

// Issue 23 item 2: a robot that filled the queue alone gives way to another robot, newest frame
// first, until neither holds two more waiting frames than the other; the rest of its frames still
// run in order.
TEST(LaneWorkQueueTest, ALaneThatFilledTheQueueGivesWayToAnother) {
  Gate gate;
  Counter started;
  Counter done;
  std::mutex mutex;
  std::map<std::string, std::vector<int>> order;
  LaneWorkQueue<TestJob> queue(1, 4, [&](TestJob& job) {
    started.Increment();
    gate.Wait();
    {
      std::lock_guard lock(mutex);
      order[job.lane].push_back(job.index);
    }
    done.Increment();
  });
  TestJob running{"a", 0};
  ASSERT_TRUE(queue.Push("a", &running).queued);
  ASSERT_TRUE(started.WaitFor(1));
  for (int i = 1; i <= 4; ++i) {
    TestJob job{"a", i};
    ASSERT_TRUE(queue.Push("a", &job).queued);
  }
  TestJob refused{"a", 5};
  EXPECT_FALSE(queue.Push("a", &refused).queued);  // a's own flood is refused
  std::vector<int> evicted;
  for (int i = 0; i < 3; ++i) {
    TestJob job{"b", i};
    auto pushed = queue.Push("b", &job);
    if (i < 2) {
      ASSERT_TRUE(pushed.queued) << i;
      ASSERT_TRUE(pushed.evicted.has_value()) << i;
      EXPECT_EQ(pushed.evicted_lane, "a");
      EXPECT_EQ(pushed.evicted_lane_waiting, 4 - i);
      EXPECT_EQ(pushed.waiting, 4);
      evicted.push_back(pushed.evicted->index);
    } else {
      // a and b hold 2 each: b is at its share.
      EXPECT_FALSE(pushed.queued);
      EXPECT_FALSE(pushed.evicted.has_value());
      EXPECT_EQ(pushed.lane_waiting, 2);
    }
  }
  EXPECT_EQ(evicted, (std::vector<int>{4, 3}));
  EXPECT_EQ(queue.depth(), 4);
  gate.Open();
  ASSERT_TRUE(done.WaitFor(5));
  std::lock_guard lock(mutex);
  EXPECT_EQ(order["a"], (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(order["b"], (std::vector<int>{0, 1}));
}

TEST(LaneWorkQueueTest, ShutdownReturnsWhatNeverStarted) {
  Gate gate;
  Counter started;
  Counter done;
  LaneWorkQueue<TestJob> queue(1, 10, [&](TestJob&) {
    started.Increment();
    gate.Wait();
    done.Increment();
  });
  for (int i = 0; i < 4; ++i) {
    TestJob job{"a", i};
    ASSERT_TRUE(queue.Push("a", &job).queued);
  }
  ASSERT_TRUE(started.WaitFor(1));
  EXPECT_EQ(queue.running(), 1);
  EXPECT_EQ(queue.depth(), 3);
  // The running job is let go only once Shutdown has taken the waiting ones (the depth drops to
  // 0 then; the one worker is blocked, so nothing else empties the queue).
  std::thread opener([&] {
    EXPECT_TRUE(Eventually([&] { return queue.depth() == 0; }, "Shutdown to take the jobs"));
    gate.Open();
  });
  const std::vector<TestJob> pending = queue.Shutdown();
  opener.join();
  EXPECT_EQ(done.value(), 1);  // the running job finished
  ASSERT_EQ(pending.size(), 3u);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(pending[i].index, i + 1);
  TestJob late{"a", 5};
  EXPECT_TRUE(queue.Push("a", &late).stopped);
  EXPECT_TRUE(queue.Shutdown().empty());
}

// The idle hook runs once when a burst of work is done, on no job's time: not while another job
// runs or waits.
TEST(LaneWorkQueueTest, IdleRunsOnceWhenTheLastJobOfABurstIsDone) {
  Gate gate;
  Counter started, finished, idle;
  std::atomic<int> busy_when_idle{0};
  std::atomic<int> running{0};
  LaneWorkQueue<TestJob> queue(
      2, 16,
      [&](TestJob&) {
        ++running;
        started.Increment();
        gate.Wait();
        --running;
        finished.Increment();
      },
      [&] {
        if (running != 0) ++busy_when_idle;
        idle.Increment();
      });
  for (int i = 0; i < 6; ++i) {
    const std::string lane = i % 2 == 0 ? "a" : "b";
    TestJob job{lane, i};
    ASSERT_TRUE(queue.Push(lane, &job).queued);
  }
  ASSERT_TRUE(started.WaitFor(2));
  EXPECT_EQ(idle.value(), 0);  // two jobs run, four wait
  gate.Open();
  ASSERT_TRUE(finished.WaitFor(6));
  ASSERT_TRUE(idle.WaitFor(1));
  ASSERT_TRUE(Eventually([&] { return queue.running() == 0; }, "the workers to finish"));
  // Of two workers finishing their last jobs together, only the one that finishes second (under
  // the queue's lock) finds nothing running.
  EXPECT_EQ(idle.value(), 1);
  EXPECT_EQ(busy_when_idle, 0);
  // A second burst: the hook again.
  const int before = idle.value();
  TestJob job{"c", 7};
  ASSERT_TRUE(queue.Push("c", &job).queued);
  ASSERT_TRUE(finished.WaitFor(7));
  ASSERT_TRUE(idle.WaitFor(before + 1));
}

}  // namespace
}  // namespace placerec
