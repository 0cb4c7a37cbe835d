#include "util/path_guard.h"

#include <sys/stat.h>

#include <filesystem>

#include "util/atomic_file.h"
#include "util/error.h"

namespace nbtf {
namespace fs = std::filesystem;

namespace {

// The path with symbolic links and `..` resolved as far as it exists, the rest normalized
// lexically: "x/../in.btf" with no folder x is "in.btf", where a write would land once the
// command had created x.
fs::path resolved(const std::string& path) {
  std::error_code ec;
  fs::path p = fs::weakly_canonical(fs::absolute(path, ec), ec);
  if (ec) p = fs::absolute(path).lexically_normal();
  return p;
}

// Same file: the same inode where both (resolved) exist, else the same resolved path.
bool sameFile(const fs::path& a, const fs::path& b) {
  struct stat sa, sb;
  const bool hasA = ::stat(a.c_str(), &sa) == 0, hasB = ::stat(b.c_str(), &sb) == 0;
  if (hasA && hasB) return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
  if (hasA != hasB) return false;
  return a == b;
}

bool isFolder(const std::string& path) {
  std::error_code ec;
  return fs::is_directory(path, ec);
}

// `inner` lies strictly inside the folder `outer`: one of inner's resolved ancestors is outer
// (by inode, or by path where outer does not exist yet).
bool inside(const fs::path& inner, const fs::path& outer) {
  for (fs::path p = inner.parent_path(); !p.empty(); p = p.parent_path()) {
    if (sameFile(p, outer)) return true;
    if (p == p.parent_path()) break;
  }
  return false;
}

std::string describe(const PathUse& use) { return use.option + " '" + use.path + "'"; }

// Why `out` (an output) must not be written, given `other` (an input, or another output); "" if fine.
std::string clash(const PathUse& out, const PathUse& other, bool otherIsInput) {
  const fs::path o = resolved(out.path), p = resolved(other.path);
  const bool otherFolder = otherIsInput ? isFolder(other.path) : other.folder;
  if (sameFile(o, p))
    return otherIsInput ? describe(out) + " is the same " + (otherFolder ? "folder" : "file") + " as the input " +
                              describe(other) + ": writing it would destroy the input"
                        : describe(out) + " and " + describe(other) +
                              " are the same file: one would overwrite the other";
  if (out.folder && inside(p, o))
    return otherIsInput ? "the output folder " + describe(out) + " holds the input " + describe(other)
                        : describe(other) + " lies inside the output folder " + describe(out);
  if (otherFolder && inside(o, p))
    return otherIsInput ? "the output " + std::string(out.folder ? "folder " : "") + describe(out) +
                              " lies inside the input folder " + describe(other) +
                              ": it could replace or add to what the command reads"
                        : describe(out) + " lies inside the output folder " + describe(other);
  return "";
}

}  // namespace

bool samePath(const std::string& a, const std::string& b) { return sameFile(resolved(a), resolved(b)); }

void refuseOverlappingPaths(const std::vector<PathUse>& inputs, const std::vector<PathUse>& outputs) {
  for (std::size_t i = 0; i < outputs.size(); ++i) {
    const PathUse& out = outputs[i];
    if (out.path.empty() || isStreamOutput(out.path)) continue;
    for (const PathUse& in : inputs) {
      if (in.path.empty() || isStreamOutput(in.path)) continue;
      const std::string why = clash(out, in, true);
      if (!why.empty()) throw Error(why + "; choose another output path (nothing was written)");
    }
    for (std::size_t j = i + 1; j < outputs.size(); ++j) {
      const PathUse& other = outputs[j];
      if (other.path.empty() || isStreamOutput(other.path)) continue;
      std::string why = clash(out, other, false);
      if (why.empty()) why = clash(other, out, false);
      if (!why.empty()) throw Error(why + "; give each output its own path (nothing was written)");
    }
  }
}

}  // namespace nbtf
