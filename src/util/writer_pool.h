// Writing files on threads of their own: every atomic write ends with an fsync, which waits on
// the disk (about 4 ms per file measured) while using no CPU, and concurrent fsyncs overlap.
// The producing threads hand finished jobs over through a bounded queue.
#pragma once
#include <algorithm>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace nbtf {

// `threads` writers over a queue of at most `capacity` jobs; after a failed job the rest are
// dropped and submit / finish rethrow its error.
class WriterPool {
 public:
  WriterPool(int threads, std::size_t capacity) : capacity_(std::max<std::size_t>(1, capacity)) {
    for (int i = 0; i < threads; ++i) threads_.emplace_back([this] { work(); });
  }
  ~WriterPool() { stop(); }

  // Blocks while the queue is full; throws the first failed write's error.
  void submit(std::function<void()> job) {
    std::unique_lock<std::mutex> lock(mutex_);
    notFull_.wait(lock, [&] { return jobs_.size() < capacity_ || error_; });
    if (error_) std::rethrow_exception(error_);
    jobs_.push_back(std::move(job));
    notEmpty_.notify_one();
  }
  // Waits for every queued write; throws the first failed write's error.
  void finish() {
    stop();
    if (error_) std::rethrow_exception(error_);
  }

 private:
  void stop() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      closing_ = true;
    }
    notEmpty_.notify_all();
    for (auto& t : threads_)
      if (t.joinable()) t.join();
  }
  void work() {
    while (true) {
      std::function<void()> job;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        notEmpty_.wait(lock, [&] { return !jobs_.empty() || closing_; });
        if (jobs_.empty()) return;
        job = std::move(jobs_.front());
        jobs_.pop_front();
        notFull_.notify_one();
        if (error_) continue;  // after a failure the rest is dropped
      }
      try {
        job();
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!error_) error_ = std::current_exception();
        notFull_.notify_all();
      }
    }
  }

  std::size_t capacity_;
  std::vector<std::thread> threads_;
  std::deque<std::function<void()>> jobs_;
  std::mutex mutex_;
  std::condition_variable notEmpty_, notFull_;
  std::exception_ptr error_;
  bool closing_ = false;
};

}  // namespace nbtf
