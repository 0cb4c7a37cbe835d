// Wall-clock seconds for stage timings, progress and budgets, on the steady clock (immune to
// changes of the system time).
#pragma once
#include <chrono>

namespace nbtf {

using Clock = std::chrono::steady_clock;

inline double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace nbtf
