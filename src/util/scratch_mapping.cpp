#include "util/scratch_mapping.h"

#include <fcntl.h>
#include <linux/magic.h>
#include <sys/mman.h>
#include <sys/statfs.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <vector>

#include "util/error.h"
#include "util/memory.h"

namespace nbtf {

namespace {

// An unnamed file in `dir`: O_TMPFILE where the file system has it, else a named one that is
// unlinked at once.
int createUnnamedFile(const std::string& dir, const std::string& what) {
  int fd = ::open(dir.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
  if (fd >= 0) return fd;
  const int tmpfileErr = errno;
  if (tmpfileErr != EOPNOTSUPP && tmpfileErr != EISDIR && tmpfileErr != EINVAL)
    throw fileAccessError(dir, "cannot create the scratch file for " + what + ": " + std::strerror(tmpfileErr),
                          tmpfileErr);
  std::string name = dir + "/.nbtf-scratch-XXXXXX";
  std::vector<char> path(name.begin(), name.end());
  path.push_back('\0');
  fd = ::mkostemp(path.data(), O_CLOEXEC);
  if (fd < 0) {
    const int err = errno;
    throw fileAccessError(dir, "cannot create the scratch file for " + what + ": " + std::strerror(err), err);
  }
  ::unlink(path.data());
  return fd;
}

}  // namespace

ScratchMapping::ScratchMapping(const std::string& dir, std::size_t bytes, const std::string& what,
                               std::size_t residentBudget, std::chrono::milliseconds trimInterval)
    : dir_(dir), size_(bytes) {
  if (bytes == 0) return;
  fd_ = createUnnamedFile(dir, what);
  // Reserve the blocks now: writing through a mapping onto a full disk raises SIGBUS.
  if (int err = ::posix_fallocate(fd_, 0, static_cast<off_t>(bytes))) {
    ::close(fd_);
    throw fileAccessError(dir,
                          "no room for the " + formatBytes(bytes) + " scratch file for " + what + " (" +
                              std::strerror(err) + "); free space there or choose another folder (--scratch-dir)",
                          err);
  }
  void* p = ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, 0);
  if (p == MAP_FAILED) {
    const int err = errno;
    ::close(fd_);
    throw fileAccessError(dir, "cannot map the scratch file for " + what + ": " + std::strerror(err), err);
  }
  data_ = static_cast<std::uint8_t*>(p);
  // Page by page, without read-ahead: pages a fault brings in are then single pages, not the
  // large folios the kernel may otherwise build, one of which maps megabytes at a time. A pass
  // that reads a few texels of every image would map all of a large stack that way, and each
  // hand-back would make it fault in everything again.
  ::madvise(data_, bytes, MADV_RANDOM);
  if (trimInterval.count() > 0)
    trimmer_ = std::thread([this, residentBudget, trimInterval] { trimLoop(residentBudget, trimInterval); });
}

ScratchMapping::~ScratchMapping() {
  if (trimmer_.joinable()) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    stopSignal_.notify_all();
    trimmer_.join();
  }
  if (data_) ::munmap(data_, size_);
  if (fd_ >= 0) ::close(fd_);
}

void ScratchMapping::releaseResident() const {
  if (!data_) return;
  // Shared file pages: dropping this process's page-table entries keeps their contents (dirty
  // ones are marked so and written back); the next access maps them again from the file cache.
  ::madvise(data_, size_, MADV_DONTNEED);
  std::lock_guard<std::mutex> lock(mutex_);
  ++releases_;
}

namespace {

// Moves `bytes` bytes at `offset` of a file of `size` bytes with `transfer` (pread or pwrite on
// `data`), resuming after short transfers and interruptions. `verb` names it in errors.
template <typename Pointer, typename Transfer>
void transferAll(const std::string& dir, std::size_t size, std::size_t offset, std::size_t bytes, Pointer data,
                 const char* verb, Transfer transfer) {
  if (offset > size || bytes > size - offset)
    throw Error("scratch file in " + dir + ": a " + verb + " of " + std::to_string(bytes) + " bytes at " +
                std::to_string(offset) + " is past its end (" + std::to_string(size) + " bytes)");
  while (bytes > 0) {
    const ssize_t n = transfer(data, bytes, static_cast<off_t>(offset));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = n < 0 ? errno : EIO;
      throw fileAccessError(dir, std::string("cannot ") + verb + " the scratch file: " + std::strerror(err), err);
    }
    data += n, offset += static_cast<std::size_t>(n), bytes -= static_cast<std::size_t>(n);
  }
}

}  // namespace

void ScratchMapping::read(std::size_t offset, std::size_t bytes, std::uint8_t* out) const {
  transferAll(dir_, size_, offset, bytes, out, "read",
              [this](std::uint8_t* p, std::size_t n, off_t at) { return ::pread(fd_, p, n, at); });
}

void ScratchMapping::write(std::size_t offset, std::size_t bytes, const std::uint8_t* in) {
  transferAll(dir_, size_, offset, bytes, in, "write",
              [this](const std::uint8_t* p, std::size_t n, off_t at) { return ::pwrite(fd_, p, n, at); });
}

std::uint64_t ScratchMapping::releases() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return releases_;
}

void ScratchMapping::trimLoop(std::size_t residentBudget, std::chrono::milliseconds interval) {
  // Other file mappings (the program's libraries) count too: measure from what they hold now.
  const std::size_t baseline = residentFileBytes();
  std::unique_lock<std::mutex> lock(mutex_);
  while (!stopSignal_.wait_for(lock, interval, [this] { return stop_; })) {
    lock.unlock();
    if (residentFileBytes() > baseline + residentBudget) releaseResident();
    lock.lock();
  }
}

std::size_t residentFileBytes() {
  // statm: size resident shared ... in pages; "shared" is RssFile + RssShmem.
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  if (!f) return 0;
  unsigned long size = 0, resident = 0, shared = 0;
  const int n = std::fscanf(f, "%lu %lu %lu", &size, &resident, &shared);
  std::fclose(f);
  return n == 3 ? static_cast<std::size_t>(shared) * static_cast<std::size_t>(::sysconf(_SC_PAGESIZE)) : 0;
}

void dropFromFileCache(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return;
  ::posix_fadvise(fd, 0, 0, POSIX_FADV_DONTNEED);
  ::close(fd);
}

bool isMemoryFileSystem(const std::string& dir) {
  struct statfs s;
  if (::statfs(dir.c_str(), &s) != 0) return false;
  return s.f_type == TMPFS_MAGIC || s.f_type == RAMFS_MAGIC;
}

}  // namespace nbtf
