// A large scratch array that lives in an unnamed file instead of the process's memory.
//
// The file is created with O_TMPFILE (or created and unlinked at once), so it has no name and
// disappears with the process, even one that is killed. Its space is reserved up front, so a
// full disk is a clear error here and not a SIGBUS in the middle of a run. The file is mapped
// shared: reading and writing are plain memory accesses. A background thread looks every
// `trimInterval` at how much of the process's resident memory is mapped from files; once that
// has grown by more than `residentBudget` since the mapping was made, it hands the mapped pages
// back (madvise MADV_DONTNEED). Their contents stay in the file and in the system's file cache,
// which the kernel may evict under pressure and read back on the next access. So the process
// holds at most about the budget of the array, and an array larger than free memory works
// (slower when the cache cannot hold it). Handing back on a budget rather than on every tick
// matters: a pass that reads the array texel by texel across all images touches thousands of
// pages per step, and each page handed back too early is faulted in again. The mapping is
// advised MADV_RANDOM, so that faults map single pages. Mapping a large array again on every
// pass still costs a fault per page, so passes that read much of it at a time use read() and
// write() (pread, pwrite: the same file cache, no mapping); docs/compress.md, *A stack in a
// scratch file*, has the figures.
#pragma once
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>

namespace nbtf {

class ScratchMapping {
 public:
  static constexpr std::chrono::milliseconds kDefaultTrimInterval{25};
  static constexpr std::size_t kDefaultResidentBudget = std::size_t(768) << 20;

  // Creates and maps `bytes` zero bytes in `dir` (which must exist). Throws nbtf::Error naming
  // `dir` and what failed (cannot create a file there, not enough free space, cannot map).
  // `what` names the contents in those errors ("the 8-bit stack"). A trimInterval of 0: no
  // background thread (releaseResident only).
  ScratchMapping(const std::string& dir, std::size_t bytes, const std::string& what,
                 std::size_t residentBudget = kDefaultResidentBudget,
                 std::chrono::milliseconds trimInterval = kDefaultTrimInterval);
  ~ScratchMapping();
  ScratchMapping(const ScratchMapping&) = delete;
  ScratchMapping& operator=(const ScratchMapping&) = delete;

  std::uint8_t* data() const { return data_; }
  std::size_t size() const { return size_; }
  const std::string& directory() const { return dir_; }
  // Copies bytes [offset, offset + bytes) into `out` with read calls (pread), which see what was
  // written through the mapping. A pass over an array larger than the budget reads it this way
  // faster than through the mapping, page fault by page fault, and the copy is not mapped.
  // Throws nbtf::FileAccessError naming the folder when the read fails.
  void read(std::size_t offset, std::size_t bytes, std::uint8_t* out) const;
  // Copies `bytes` bytes from `in` to [offset, offset + bytes) with write calls (pwrite): no page
  // faults, and the mapping sees the bytes at once. Throws like read.
  void write(std::size_t offset, std::size_t bytes, const std::uint8_t* in);
  // Hands every mapped page back now (what the background thread does each interval).
  void releaseResident() const;
  // How many times the pages were handed back so far.
  std::uint64_t releases() const;

 private:
  void trimLoop(std::size_t residentBudget, std::chrono::milliseconds interval);

  std::string dir_;
  int fd_ = -1;
  std::uint8_t* data_ = nullptr;
  std::size_t size_ = 0;
  mutable std::mutex mutex_;
  std::condition_variable stopSignal_;
  bool stop_ = false;
  mutable std::uint64_t releases_ = 0;
  std::thread trimmer_;
};

// This process's resident pages mapped from files (RssFile + RssShmem; /proc/self/statm), bytes.
std::size_t residentFileBytes();

// Asks the kernel to drop `path`'s clean pages from the file cache (posix_fadvise
// POSIX_FADV_DONTNEED); a file that cannot be opened is left alone. A loader that fills a
// scratch array from source files calls it after each file: the sources are read once, and
// keeping them cached would push the array's own cached pages out, which are then read back
// from disk one page at a time.
void dropFromFileCache(const std::string& path);

// Whether `dir` is on a file system that lives in memory (tmpfs, ramfs): a scratch file there
// takes as much memory as the array it replaces.
bool isMemoryFileSystem(const std::string& dir);

}  // namespace nbtf
