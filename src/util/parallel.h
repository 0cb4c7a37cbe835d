// Thread count and a small parallel-for used by every CPU stage.
//
// Two pools, on purpose: these helpers start their own threads (no dependency, so the
// decoder library stays std-only), while the model's kernels (src/model/) run on libgomp's
// OpenMP pool through at::parallel_for, because libtorch's own operators in the same training
// step run there: a second pool beside it would oversubscribe the cores. The two never run at
// once, and both take their size from threadCount() (the model sets torch's from it).
#pragma once
#include <cstddef>
#include <functional>

namespace nbtf {

// Threads used by nbtf stages: set once from --threads; 0 means all cores.
void setThreadCount(int threads);
int threadCount();

// Calls body(begin, end) on disjoint chunks of [0, n) from threadCount() threads.
// Exceptions thrown by a chunk are rethrown on the caller (the first one wins).
void parallelFor(std::size_t n, const std::function<void(std::size_t, std::size_t)>& body,
                 std::size_t minChunk = 1);

// Dynamic scheduling: each index is handed out on demand (good for uneven work like
// image decoding). body(index, workerId).
void parallelForDynamic(std::size_t n, const std::function<void(std::size_t, int)>& body);

}  // namespace nbtf
