// The sweep's disk worker (pipeline/background_queue.hpp): tasks run in the
// order posted, on one other thread; at most `capacity` wait; a task's
// exception reaches the poster and drops what was queued after it.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>
#include <vector>

#include "pipeline/background_queue.hpp"

using raysweep::pipeline::BackgroundQueue;

TEST(BackgroundQueue, RunsTasksInOrderOnAnotherThread) {
  std::vector<int> seen;
  std::thread::id worker;
  {
    BackgroundQueue q(2, false);
    for (int i = 0; i < 200; ++i)
      q.post([&, i] {
        seen.push_back(i);  // one worker: no two tasks at once
        worker = std::this_thread::get_id();
      });
    q.finish();
    ASSERT_EQ(seen.size(), 200u);
    for (int i = 0; i < 200; ++i) EXPECT_EQ(seen[i], i);
    EXPECT_NE(worker, std::this_thread::get_id());
  }
}

TEST(BackgroundQueue, InlineRunsInPost) {
  BackgroundQueue q(2, true);
  std::thread::id ran;
  q.post([&] { ran = std::this_thread::get_id(); });
  EXPECT_EQ(ran, std::this_thread::get_id());
  EXPECT_THROW(q.post([] { throw std::runtime_error("disk full"); }), std::runtime_error);
}

TEST(BackgroundQueue, PostBlocksAtCapacity) {
  std::atomic<bool> started{false}, release{false}, posted{false};
  std::atomic<int> done{0};
  BackgroundQueue q(1, false);
  q.post([&] {
    started = true;
    while (!release) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    ++done;
  });
  while (!started) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  q.post([&] { ++done; });  // waits: the queue is now full
  std::thread poster([&] {
    q.post([&] { ++done; });
    posted = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_FALSE(posted) << "post() returned with the queue full";
  release = true;
  poster.join();
  EXPECT_TRUE(posted);
  q.finish();
  EXPECT_EQ(done, 3);
}

TEST(BackgroundQueue, ExceptionReachesThePosterAndDropsTheRest) {
  BackgroundQueue q(4, false);
  std::atomic<bool> go{false};
  std::atomic<int> after{0};
  q.post([&] {
    while (!go) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    throw std::runtime_error("cannot write block");
  });
  q.post([&] { ++after; });  // queued behind the failing task: dropped
  go = true;
  try {
    q.finish();
    FAIL() << "finish() did not rethrow";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "cannot write block");
  }
  EXPECT_EQ(after, 0);
  // The queue goes on after the error was reported.
  q.post([&] { ++after; });
  q.finish();
  EXPECT_EQ(after, 1);
}

TEST(BackgroundQueue, DestructorDropsPendingTasksAndJoins) {
  std::atomic<int> ran{0};
  std::atomic<bool> started{false}, go{false};
  std::thread releaser([&] {
    while (!started) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    go = true;
  });
  {
    BackgroundQueue q(8, false);
    q.post([&] {
      started = true;
      while (!go) std::this_thread::sleep_for(std::chrono::milliseconds(1));
      ++ran;
    });
    while (!started) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    for (int i = 0; i < 5; ++i) q.post([&] { ran += 100; });
  }  // waits for the running task; the five behind it never run
  releaser.join();
  EXPECT_EQ(ran, 1);
}
