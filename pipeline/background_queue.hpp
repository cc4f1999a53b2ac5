// One worker thread that runs tasks in the order they are posted: a sweep's
// disk work (encoding frame blocks, compressing the dataset's chunks) runs
// while the tracer works on the next frames, on the core time the tracer's
// serial parts leave idle.
//
// At most `capacity` tasks wait; post() blocks beyond that (a task may hold a
// frame of several MB). The first exception a task throws is rethrown by the
// next post() or by finish(), and the tasks queued after it are dropped. With
// `run_inline` (one thread allowed: `raysweep -j 1`) every task runs inside
// post() instead. The destructor drops the tasks not started and waits for
// the running one, so an error on the posting side unwinds cleanly.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <utility>

namespace raysweep::pipeline {

class BackgroundQueue {
 public:
  BackgroundQueue(std::size_t capacity, bool run_inline) : capacity_(capacity < 1 ? 1 : capacity), inline_(run_inline) {
    if (!inline_) worker_ = std::thread([this] { run(); });
  }
  ~BackgroundQueue() {
    if (inline_) return;
    {
      std::lock_guard lock(m_);
      stop_ = true;
      q_.clear();
    }
    cv_.notify_all();
    worker_.join();
  }
  BackgroundQueue(const BackgroundQueue&) = delete;
  BackgroundQueue& operator=(const BackgroundQueue&) = delete;

  void post(std::function<void()> task) {
    if (inline_) {
      task();
      return;
    }
    std::unique_lock lock(m_);
    cv_.wait(lock, [&] { return q_.size() < capacity_ || error_; });
    rethrow(lock);
    q_.push_back(std::move(task));
    cv_.notify_all();
  }

  // Waits until every posted task has run; rethrows the first failure.
  void finish() {
    if (inline_) return;
    std::unique_lock lock(m_);
    cv_.wait(lock, [&] { return (q_.empty() && !busy_) || error_; });
    rethrow(lock);
  }

 private:
  void rethrow(std::unique_lock<std::mutex>&) {
    if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
  }
  void run() {
    std::unique_lock lock(m_);
    for (;;) {
      cv_.wait(lock, [&] { return stop_ || !q_.empty(); });
      if (stop_) return;
      std::function<void()> task = std::move(q_.front());
      q_.pop_front();
      busy_ = true;
      lock.unlock();
      std::exception_ptr failed;
      try {
        task();
      } catch (...) {
        failed = std::current_exception();
      }
      task = nullptr;  // a frame it held is freed outside the lock
      lock.lock();
      busy_ = false;
      if (failed) {
        error_ = failed;
        q_.clear();
      }
      cv_.notify_all();
    }
  }

  std::mutex m_;
  std::condition_variable cv_;
  std::deque<std::function<void()>> q_;
  bool stop_ = false, busy_ = false;
  std::exception_ptr error_;
  std::size_t capacity_;
  bool inline_;
  std::thread worker_;
};

}  // namespace raysweep::pipeline
