#include "util/output_folder.h"

#include <stdlib.h>
#include <sys/stat.h>

#include <cerrno>
#include <cstring>
#include <fstream>

#include "util/error.h"

namespace nbtf {
namespace fs = std::filesystem;
namespace {

fs::path makeTempFolder(const fs::path& dir, const char* tag) {
  const fs::path parent = dir.parent_path().empty() ? fs::path(".") : dir.parent_path();
  std::string tmpl = (parent / ("." + dir.filename().string() + tag + "XXXXXX")).string();
  if (!mkdtemp(tmpl.data()))
    throw Error(dir.string() + ": cannot create a temporary folder beside it (" + std::strerror(errno) + ")");
  // mkdtemp makes it 0700; the output becomes this folder, so give it the mode every other
  // output folder gets (0777 less the umask).
  const mode_t mask = ::umask(0);
  ::umask(mask);
  ::chmod(tmpl.c_str(), 0777 & ~mask);
  return tmpl;
}

fs::path folderPath(const std::string& text, const std::string& what) {
  fs::path dir(text);
  while (!dir.empty() && dir.filename().empty()) dir = dir.parent_path();  // "out/" -> "out"
  if (dir.empty()) throw Error(what + ": empty output folder name");
  return dir;
}

}  // namespace

void writeWholeFile(const fs::path& path, const void* data, std::size_t size) {
  std::ofstream f(path, std::ios::binary);
  if (f) f.write(static_cast<const char*>(data), static_cast<std::streamsize>(size));
  if (f) f.flush();
  if (!f) throw Error(path.string() + ": cannot write (" + std::strerror(errno) + ")");
}

void checkReplaceableFolder(const std::string& text, const OutputFolderKind& kind) {
  const fs::path dir = folderPath(text, kind.what);
  std::error_code ec;
  if (!fs::exists(dir, ec)) return;
  if (!fs::is_directory(dir, ec)) throw Error(dir.string() + ": exists and is not a folder");
  if (fs::is_empty(dir, ec)) return;
  const bool ours = fs::exists(dir / kind.marker, ec) && (!kind.isOurs || kind.isOurs(dir));
  if (!ours)
    throw Error(dir.string() + ": exists and is not " + kind.what + " (no " + kind.marker +
                " written by nbtf); give a new or empty folder");
}

void writeFolderAtomic(const std::string& text, const OutputFolderKind& kind,
                       const std::function<void(const fs::path&)>& write) {
  checkReplaceableFolder(text, kind);
  const fs::path dir = folderPath(text, kind.what);
  std::error_code ec;
  if (!dir.parent_path().empty()) fs::create_directories(dir.parent_path(), ec);
  const fs::path tmp = makeTempFolder(dir, ".tmp-");
  try {
    write(tmp);
    if (fs::exists(dir, ec)) {
      const fs::path old = makeTempFolder(dir, ".old-");
      fs::rename(dir, old);  // onto the empty folder just made
      try {
        fs::rename(tmp, dir);
      } catch (...) {
        fs::rename(old, dir, ec);
        throw;
      }
      fs::remove_all(old, ec);
    } else {
      fs::rename(tmp, dir);
    }
  } catch (const fs::filesystem_error& e) {
    fs::remove_all(tmp, ec);
    throw Error(dir.string() + ": cannot write " + kind.what + " (" + e.code().message() + ")");
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
}

}  // namespace nbtf
