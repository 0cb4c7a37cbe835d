#include "util/parallel.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace nbtf {
namespace {
std::atomic<int> g_threads{0};

// Runs worker(id) on `count` threads (the caller's thread is worker 0) and rethrows
// the first exception.
void runWorkers(int count, const std::function<void(int)>& worker) {
  std::exception_ptr first;
  std::mutex mutex;
  auto guarded = [&](int id) {
    try {
      worker(id);
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex);
      if (!first) first = std::current_exception();
    }
  };
  std::vector<std::thread> threads;
  for (int id = 1; id < count; ++id) threads.emplace_back(guarded, id);
  guarded(0);
  for (auto& t : threads) t.join();
  if (first) std::rethrow_exception(first);
}
}  // namespace

void setThreadCount(int threads) { g_threads = std::max(0, threads); }

int threadCount() {
  int t = g_threads.load();
  if (t > 0) return t;
  return std::max(1u, std::thread::hardware_concurrency());
}

void parallelFor(std::size_t n, const std::function<void(std::size_t, std::size_t)>& body,
                 std::size_t minChunk) {
  if (n == 0) return;
  std::size_t workers = std::min<std::size_t>(threadCount(), (n + minChunk - 1) / std::max<std::size_t>(1, minChunk));
  workers = std::max<std::size_t>(1, workers);
  if (workers == 1) {
    body(0, n);
    return;
  }
  std::size_t chunk = (n + workers - 1) / workers;
  runWorkers(static_cast<int>(workers), [&](int id) {
    std::size_t begin = id * chunk, end = std::min(n, begin + chunk);
    if (begin < end) body(begin, end);
  });
}

void parallelForDynamic(std::size_t n, const std::function<void(std::size_t, int)>& body) {
  if (n == 0) return;
  std::atomic<std::size_t> next{0};
  std::atomic<bool> failed{false};
  int workers = static_cast<int>(std::min<std::size_t>(threadCount(), n));
  runWorkers(workers, [&](int id) {
    try {
      for (std::size_t i = next++; i < n && !failed; i = next++) body(i, id);
    } catch (...) {
      failed = true;
      throw;
    }
  });
}

}  // namespace nbtf
