#include "util/atomic_file.h"

#include <fcntl.h>
#include <sys/stat.h>
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

bool isStreamOutput(const std::string& path) {
  if (path.rfind("/dev/", 0) == 0 || path.rfind("/proc/", 0) == 0) return true;
  struct stat st;
  return ::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode);
}

std::string temporaryPathFor(const std::string& path) {
  static std::atomic<unsigned> counter{0};
  fs::path p(path);
  std::string name = "." + p.filename().string() + ".tmp" + std::to_string(::getpid()) + "_" +
                     std::to_string(counter++);
  // Keep the extension last so extension-sniffing writers (OpenCV, OpenEXR) still work.
  name += p.extension().string();
  return (p.parent_path() / name).string();
}

bool isTemporaryNameFor(const std::string& fileName, const std::string& targetName) {
  return fileName.rfind("." + targetName + ".tmp", 0) == 0;
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

namespace {


// Through symbolic links to the file they name (so the link stays a link and its target is
// replaced); the path itself when it is not a link.
std::string linkTarget(const std::string& path) {
  fs::path p(path);
  std::error_code ec;
  for (int depth = 0; depth < 40 && fs::is_symlink(fs::symlink_status(p, ec)); ++depth) {
    fs::path target = fs::read_symlink(p, ec);
    if (ec) throw fileError(path, "cannot read the symbolic link: " + ec.message());
    p = target.is_absolute() ? target : p.parent_path() / target;
  }
  return p.string();
}

void writeStream(const std::string& path, const void* data, std::size_t size) {
  int fd = ::open(path.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC);
  if (fd < 0) throw fileAccessError(path, std::string("cannot open for writing: ") + std::strerror(errno), errno);
  const char* p = static_cast<const char*>(data);
  while (size > 0) {
    ssize_t n = ::write(fd, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      int err = errno;
      ::close(fd);
      throw fileAccessError(path, std::string("write failed: ") + std::strerror(err), err);
    }
    p += n, size -= static_cast<std::size_t>(n);
  }
  ::close(fd);
}

}  // namespace

void writeFileAtomic(const std::string& requested, const void* data, std::size_t size) {
  if (isStreamOutput(requested)) return writeStream(requested, data, size);
  const std::string path = linkTarget(requested);
  std::string tmp = temporaryPathFor(path);
  FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) throw fileAccessError(path, std::string("cannot create file: ") + std::strerror(errno), errno);
  bool ok = std::fwrite(data, 1, size, f) == size;
  int err = errno;
  ok = (std::fflush(f) == 0) && ok;
  if (!ok) err = errno;
  ok = (std::fclose(f) == 0) && ok;
  if (!ok) {
    std::remove(tmp.c_str());
    throw fileAccessError(path, std::string("write failed (disk full?): ") + std::strerror(err), err);
  }
  syncAndRename(tmp, path);
}

void writeAtomicVia(const std::string& requested, const std::function<void(const std::string&)>& write) {
  const bool stream = isStreamOutput(requested);
  // A device or pipe: the writer needs a file, so it writes one in the temporary folder
  // whose bytes are then copied out.
  const std::string path = stream ? requested : linkTarget(requested);
  std::string tmp = stream ? (fs::temp_directory_path() / fs::path(temporaryPathFor(path)).filename()).string()
                           : temporaryPathFor(path);
  try {
    write(tmp);
  } catch (...) {
    std::remove(tmp.c_str());
    throw;
  }
  std::error_code ec;
  if (!fs::exists(tmp, ec)) throw fileError(path, "writer produced no file");
  if (stream) {
    std::vector<std::uint8_t> bytes;
    try {
      bytes = readFileBytes(tmp);
    } catch (...) {
      std::remove(tmp.c_str());
      throw;
    }
    std::remove(tmp.c_str());
    return writeStream(path, bytes.data(), bytes.size());
  }
  syncAndRename(tmp, path);
}

std::vector<std::uint8_t> readFileBytes(const std::string& path) {
  std::error_code ec;
  // A folder opens as a stream on Linux and reports an absurd size: name it instead.
  if (fs::is_directory(path, ec)) throw fileAccessError(path, "is a folder, expected a file", EISDIR);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw fileAccessError(path, std::string("cannot open file: ") + std::strerror(errno), errno);
  in.seekg(0, std::ios::end);
  std::streamoff size = in.tellg();
  if (size < 0) throw fileError(path, "cannot determine file size");
  in.seekg(0);
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
  if (size > 0 && !in.read(reinterpret_cast<char*>(bytes.data()), size))
    throw fileAccessError(path, "read failed", EIO);
  return bytes;
}

void checkWritable(const std::string& requested) {
  if (isStreamOutput(requested)) {  // written in place: it must exist and take writes
    if (::access(requested.c_str(), W_OK) != 0)
      throw fileAccessError(requested, std::string("cannot write to it: ") + std::strerror(errno), errno);
    return;
  }
  const std::string path = linkTarget(requested);
  fs::path p(path);
  fs::path dir = p.parent_path().empty() ? fs::path(".") : p.parent_path();
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec))
    throw fileAccessError(path, "'" + dir.string() + "' is a file, not a folder", ENOTDIR);
  if (!fs::is_directory(dir, ec))
    throw fileAccessError(path, "output folder '" + dir.string() + "' does not exist", ENOENT);
  if (::access(dir.c_str(), W_OK) != 0)
    throw fileAccessError(path, "output folder '" + dir.string() + "' is not writable", EACCES);
  if (fs::is_directory(p, ec))
    throw fileAccessError(path, "output path is a folder, expected a file name", EISDIR);
  // A real probe: create and remove a small file (catches read-only mounts, full disks).
  std::string probe = temporaryPathFor(path);
  FILE* f = std::fopen(probe.c_str(), "wb");
  if (!f)
    throw fileAccessError(path, std::string("cannot create files in output folder: ") + std::strerror(errno), errno);
  char buf[4096] = {};
  bool ok = std::fwrite(buf, 1, sizeof buf, f) == sizeof buf && std::fflush(f) == 0;
  int err = errno;
  std::fclose(f);
  std::remove(probe.c_str());
  if (!ok) throw fileAccessError(path, std::string("cannot write to output folder: ") + std::strerror(err), err);
}

void createParentFolders(const std::string& path) {
  if (isStreamOutput(path)) return;
  fs::path dir = fs::path(linkTarget(path)).parent_path();
  if (dir.empty()) return;
  std::error_code ec;
  // A file where a folder should be ("some.nbtf/a.png"): name it, not "does not exist".
  for (fs::path p = dir; !p.empty() && p != p.parent_path(); p = p.parent_path())
    if (fs::exists(p, ec)) {
      if (!fs::is_directory(p, ec))
        throw fileAccessError(path,
                              "cannot create the folder '" + dir.string() + "': '" + p.string() +
                                  "' is a file, not a folder",
                              ENOTDIR);
      break;
    }
  fs::create_directories(dir, ec);
  if (ec) throw fileAccessError(path, "cannot create the folder '" + dir.string() + "': " + ec.message(), ec.value());
}

}  // namespace nbtf
