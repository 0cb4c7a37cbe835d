// Work of a training step handed to torch's threads an item at a time. PRIVATE to
// src/model/ (includes ATen). (util/parallel.h's parallelForDynamic starts threads of its
// own on every call: right for loading images, too slow for the millisecond passes of a step,
// and a second pool beside torch's.)
#pragma once
#include <ATen/Parallel.h>

#include <algorithm>
#include <atomic>
#include <cstdint>

namespace nbtf::detail {

// Threads forEachItemDynamic runs for `items` items: torch's thread count, at most one per item.
inline int dynamicSlots(std::int64_t items) {
  return static_cast<int>(std::max<std::int64_t>(1, std::min<std::int64_t>(at::get_num_threads(), items)));
}

// Runs work(slot, take) once for every slot < dynamicSlots(items), on torch's threads; slot
// picks the thread's scratch, take() hands out the next item of [0, items) (-1 when none is
// left). A thread the host slows down does not hold the others up. Callers keep each item's
// results apart and combine them in item order, so results do not depend on which thread ran
// which item.
template <class Work>
void forEachItemDynamic(std::int64_t items, const Work& work) {
  std::atomic<std::int64_t> next{0};
  auto take = [&]() -> std::int64_t {
    const std::int64_t item = next++;
    return item < items ? item : -1;
  };
  const int slots = dynamicSlots(items);
  if (slots == 1) return work(0, take);
  at::parallel_for(0, slots, 1, [&](std::int64_t begin, std::int64_t end) {
    for (std::int64_t slot = begin; slot < end; ++slot) work(static_cast<int>(slot), take);
  });
}

}  // namespace nbtf::detail
