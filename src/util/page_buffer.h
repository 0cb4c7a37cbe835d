// A large zero-filled byte buffer taken straight from the kernel.
//
// Anonymous pages arrive zeroed and are faulted in by the thread that first writes them, so a
// buffer that is about to be filled in parallel costs no serial memset (std::vector's resize
// zeroes every byte on one thread, then each page faults in). Buffers of 2 MiB or more are
// aligned to 2 MiB and advised MADV_HUGEPAGE: where the system grants transparent huge pages on
// request (the common "madvise" setting), a 1.2 GiB stack faults in 2 MiB at a time, about 600
// faults instead of 300,000, and the passes that read it across images miss the TLB less. On
// systems that refuse, the buffer is the same, in 4 KiB pages.
#pragma once
#include <cstddef>
#include <cstdint>

namespace nbtf {

class PageBuffer {
 public:
  PageBuffer() = default;
  // `bytes` zero bytes; throws nbtf::Error when the memory cannot be had.
  explicit PageBuffer(std::size_t bytes);
  ~PageBuffer();
  PageBuffer(const PageBuffer& other);
  PageBuffer& operator=(const PageBuffer& other);
  PageBuffer(PageBuffer&& other) noexcept;
  PageBuffer& operator=(PageBuffer&& other) noexcept;

  std::uint8_t* data() { return data_; }
  const std::uint8_t* data() const { return data_; }
  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }

 private:
  void release() noexcept;
  std::uint8_t* data_ = nullptr;
  std::size_t size_ = 0;
  std::size_t mapped_ = 0;  // bytes mapped at data_ (size_ rounded up to whole pages)
};

}  // namespace nbtf
