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

template <typename Predicate>
bool WaitUntil(Predicate done) {
  for (int i = 0; i < 5000; ++i) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return done();
}

TEST(LaneWorkQueueTest, EachLaneInOrderAndNeverTwiceAtOnce) {
  std::mutex mutex;
  std::map<std::string, std::vector<int>> order;
  std::map<std::string, int> running;
  bool overlap = false;
  std::atomic<int> max_running{0};
  std::atomic<int> now_running{0};
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
      std::this_thread::sleep_for(std::chrono::microseconds(200));
      --now_running;
      std::lock_guard lock(mutex);
      --running[job.lane];
      order[job.lane].push_back(job.index);
    });
    for (int i = 0; i < 60; ++i) {
      for (const char* lane : {"a", "b", "c"}) {
        TestJob job{lane, i};
        ASSERT_TRUE(queue.Push(lane, &job));
      }
    }
    ASSERT_TRUE(WaitUntil([&] {
      std::lock_guard lock(mutex);
      return order["a"].size() + order["b"].size() + order["c"].size() == 180;
    }));
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
  std::atomic<int> done{0};
  LaneWorkQueue<TestJob> queue(2, 3, [&](TestJob&) {
    gate.Wait();
    ++done;
  });
  TestJob a{"a", 0};
  TestJob b{"b", 0};
  ASSERT_TRUE(queue.Push("a", &a));
  ASSERT_TRUE(queue.Push("b", &b));
  ASSERT_TRUE(WaitUntil([&] { return queue.running() == 2; }));
  for (int i = 1; i <= 3; ++i) {
    TestJob job{"a", i};
    ASSERT_TRUE(queue.Push("a", &job));
  }
  EXPECT_EQ(queue.depth(), 3);
  TestJob refused{"c", 9};
  EXPECT_FALSE(queue.Push("c", &refused));
  EXPECT_EQ(refused.lane, "c");  // left untouched
  EXPECT_EQ(refused.index, 9);
  gate.Open();
  ASSERT_TRUE(WaitUntil([&] { return done.load() == 5; }));
  EXPECT_EQ(queue.depth(), 0);
  TestJob again{"c", 10};
  EXPECT_TRUE(queue.Push("c", &again));
}

TEST(LaneWorkQueueTest, ShutdownReturnsWhatNeverStarted) {
  Gate gate;
  std::atomic<int> done{0};
  LaneWorkQueue<TestJob> queue(1, 10, [&](TestJob&) {
    gate.Wait();
    ++done;
  });
  for (int i = 0; i < 4; ++i) {
    TestJob job{"a", i};
    ASSERT_TRUE(queue.Push("a", &job));
  }
  ASSERT_TRUE(WaitUntil([&] { return queue.running() == 1; }));
  std::thread opener([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    gate.Open();
  });
  const std::vector<TestJob> pending = queue.Shutdown();
  opener.join();
  EXPECT_EQ(done.load(), 1);  // the running job finished
  ASSERT_EQ(pending.size(), 3u);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(pending[i].index, i + 1);
  TestJob late{"a", 5};
  EXPECT_FALSE(queue.Push("a", &late));
  EXPECT_TRUE(queue.Shutdown().empty());
}

}  // namespace
}  // namespace placerec
