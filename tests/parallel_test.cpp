#include "util/parallel.h"

#include <gtest/gtest.h>

#include <atomic>
#include <numeric>
#include <vector>

#include "util/error.h"

namespace nbtf {

TEST(Parallel, CoversEveryIndexOnce) {
  for (int threads : {1, 2, 5}) {
    setThreadCount(threads);
    std::vector<std::atomic<int>> hits(1000);
    parallelFor(hits.size(), [&](std::size_t b, std::size_t e) {
      for (std::size_t i = b; i < e; ++i) hits[i]++;
    });
    parallelForDynamic(hits.size(), [&](std::size_t i, int) { hits[i]++; });
    for (auto& h : hits) EXPECT_EQ(h.load(), 2);
  }
  setThreadCount(0);
  EXPECT_GE(threadCount(), 1);
}

TEST(Parallel, ExceptionsReachTheCaller) {
  setThreadCount(2);
  EXPECT_THROW(parallelForDynamic(100, [](std::size_t i, int) { if (i == 57) throw Error("bad item 57"); }), Error);
  EXPECT_THROW(parallelFor(100, [](std::size_t b, std::size_t) { if (b > 0) throw Error("bad chunk"); }), Error);
  setThreadCount(0);
}

}  // namespace nbtf
