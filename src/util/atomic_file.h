// Atomic output: write to a temporary name beside the target, fsync, then rename,
// so a crash or kill never leaves a half-written file under the final name. Only regular
// files are replaced: a symbolic link is followed to its target (the link stays), and a
// device, pipe or socket (`/dev/stdout`, `/dev/null`, a FIFO; anything under /dev or /proc)
// is written in place, never unlinked.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace nbtf {

// Writes `bytes` to `path` atomically. Throws nbtf::Error naming the path on failure.
void writeFileAtomic(const std::string& path, const void* data, std::size_t size);
inline void writeFileAtomic(const std::string& path, const std::string& text) {
  writeFileAtomic(path, text.data(), text.size());
}

// For writers that need a file name (OpenCV, OpenEXR): `write(tmpPath)` writes the
// temporary file, which is then fsynced and renamed onto `path`. On any failure the
// temporary is removed and an nbtf::Error is thrown.
void writeAtomicVia(const std::string& path, const std::function<void(const std::string&)>& write);

// An output that is not replaced but written in place: a device, pipe or socket
// (`/dev/stdout`, `/dev/null`, a FIFO), or anything under /dev and /proc (whose links lead to
// such things, or to the file the shell redirected stdout to).
bool isStreamOutput(const std::string& path);

// The temporary name used for `path` (same folder, so rename stays atomic).
std::string temporaryPathFor(const std::string& path);
// Whether `fileName` (a name, no folder) is one of temporaryPathFor's names for a file named
// `targetName`: what a kill during writeFileAtomic(targetName) leaves.
bool isTemporaryNameFor(const std::string& fileName, const std::string& targetName);

// Reads a whole file; throws nbtf::Error naming the path if it cannot.
std::vector<std::uint8_t> readFileBytes(const std::string& path);

// Throws a clear error now (before hours of work) if `path` cannot be created:
// its folder must exist and be writable (a device or pipe: it must take writes).
void checkWritable(const std::string& path);

// Creates the missing folders above `path` (the one rule of every command's outputs).
void createParentFolders(const std::string& path);

}  // namespace nbtf
