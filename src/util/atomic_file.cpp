#include "util/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "util/error.h"

namespace nbtf {
namespace fs = std::filesystem;

std::string temporaryPathFor(const std::string& path) {
  static std::atomic<unsigned> counter{0};
  fs::path p(path);
  std::string name = "." + p.filename().string() + ".tmp" + std::to_string(::getpid()) + "_" +
                     std::to_string(counter++);
  // Keep the extension last so extension-sniffing writers (OpenCV, OpenEXR) still work.
  name += p.extension().string();
  return (p.parent_path() / name).string();
}

namespace {
void syncAndRename(const std::string& tmp, const std::string& path) {
  int fd = ::open(tmp.c_str(), O_RDONLY);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    int err = errno;
    std::remove(tmp.c_str());
    throw fileError(path, std::string("cannot rename temporary file into place: ") + std::strerror(err));
  }
}
}  // namespace

void writeFileAtomic(const std::string& path, const void* data, std::size_t size) {
  std::string tmp = temporaryPathFor(path);
  FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) throw fileError(path, std::string("cannot create file: ") + std::strerror(errno));
  bool ok = std::fwrite(data, 1, size, f) == size;
  int err = errno;
  ok = (std::fflush(f) == 0) && ok;
  if (!ok) err = errno;
  ok = (std::fclose(f) == 0) && ok;
  if (!ok) {
    std::remove(tmp.c_str());
    throw fileError(path, std::string("write failed (disk full?): ") + std::strerror(err));
  }
  syncAndRename(tmp, path);
}

void writeAtomicVia(const std::string& path, const std::function<void(const std::string&)>& write) {
  std::string tmp = temporaryPathFor(path);
  try {
    write(tmp);
  } catch (...) {
    std::remove(tmp.c_str());
    throw;
  }
  std::error_code ec;
  if (!fs::exists(tmp, ec)) throw fileError(path, "writer produced no file");
  syncAndRename(tmp, path);
}

std::vector<std::uint8_t> readFileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw fileError(path, std::string("cannot open file: ") + std::strerror(errno));
  in.seekg(0, std::ios::end);
  std::streamoff size = in.tellg();
  if (size < 0) throw fileError(path, "cannot determine file size");
  in.seekg(0);
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
  if (size > 0 && !in.read(reinterpret_cast<char*>(bytes.data()), size))
    throw fileError(path, "read failed");
  return bytes;
}

void checkWritable(const std::string& path) {
  fs::path p(path);
  fs::path dir = p.parent_path().empty() ? fs::path(".") : p.parent_path();
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw fileError(path, "output folder '" + dir.string() + "' does not exist");
  if (::access(dir.c_str(), W_OK) != 0)
    throw fileError(path, "output folder '" + dir.string() + "' is not writable");
  if (fs::is_directory(p, ec)) throw fileError(path, "output path is a folder, expected a file name");
  // A real probe: create and remove a small file (catches read-only mounts, full disks).
  std::string probe = temporaryPathFor(path);
  FILE* f = std::fopen(probe.c_str(), "wb");
  if (!f) throw fileError(path, std::string("cannot create files in output folder: ") + std::strerror(errno));
  char buf[4096] = {};
  bool ok = std::fwrite(buf, 1, sizeof buf, f) == sizeof buf && std::fflush(f) == 0;
  int err = errno;
  std::fclose(f);
  std::remove(probe.c_str());
  if (!ok) throw fileError(path, std::string("cannot write to output folder: ") + std::strerror(err));
}

}  // namespace nbtf
