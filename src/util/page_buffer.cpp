#include "util/page_buffer.h"

#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>
#include <utility>

#include "util/error.h"

namespace nbtf {

namespace {

constexpr std::size_t kHugePage = std::size_t(2) << 20;

std::size_t roundUp(std::size_t bytes, std::size_t unit) { return (bytes + unit - 1) / unit * unit; }

}  // namespace

PageBuffer::PageBuffer(std::size_t bytes) {
  if (bytes == 0) return;
  const bool huge = bytes >= kHugePage;
  const std::size_t page = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
  const std::size_t mapped = roundUp(bytes, huge ? kHugePage : page);
  // For huge pages, one extra huge page of address space, so that a 2 MiB-aligned start exists;
  // the unused head and tail are unmapped at once.
  const std::size_t reserve = huge ? mapped + kHugePage : mapped;
  void* p = ::mmap(nullptr, reserve, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED)
    throw Error("cannot allocate " + std::to_string(bytes) + " bytes of memory: " + std::strerror(errno));
  auto* start = static_cast<std::uint8_t*>(p);
  if (huge) {
    const std::uintptr_t at = reinterpret_cast<std::uintptr_t>(start);
    auto* aligned = reinterpret_cast<std::uint8_t*>(roundUp(at, kHugePage));
    const std::size_t head = static_cast<std::size_t>(aligned - start), tail = reserve - head - mapped;
    if (head > 0) ::munmap(start, head);
    if (tail > 0) ::munmap(aligned + mapped, tail);
    start = aligned;
    ::madvise(start, mapped, MADV_HUGEPAGE);  // advice only: refused, the pages stay 4 KiB
  }
  data_ = start;
  size_ = bytes;
  mapped_ = mapped;
}

PageBuffer::~PageBuffer() { release(); }

void PageBuffer::release() noexcept {
  if (data_) ::munmap(data_, mapped_);
  data_ = nullptr;
  size_ = mapped_ = 0;
}

PageBuffer::PageBuffer(const PageBuffer& other) : PageBuffer(other.size_) {
  if (size_) std::memcpy(data_, other.data_, size_);
}

PageBuffer& PageBuffer::operator=(const PageBuffer& other) {
  if (this != &other) *this = PageBuffer(other);
  return *this;
}

PageBuffer::PageBuffer(PageBuffer&& other) noexcept
    : data_(std::exchange(other.data_, nullptr)),
      size_(std::exchange(other.size_, 0)),
      mapped_(std::exchange(other.mapped_, 0)) {}

PageBuffer& PageBuffer::operator=(PageBuffer&& other) noexcept {
  if (this != &other) {
    release();
    data_ = std::exchange(other.data_, nullptr);
    size_ = std::exchange(other.size_, 0);
    mapped_ = std::exchange(other.mapped_, 0);
  }
  return *this;
}

}  // namespace nbtf
