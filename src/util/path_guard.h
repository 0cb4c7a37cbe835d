// Refusing, before any work, an output that would overwrite one of the command's inputs or
// another of its outputs. Paths are compared as the file system sees them: through symbolic
// links and `..` (the canonical path), and by device and inode where the file exists, so a
// hard link or a bind mount of an input is caught too.
#pragma once
#include <string>
#include <vector>

namespace nbtf {

// One path a command reads or writes, with the option that named it ("-o", "--stats-json",
// "<input>") for the error. `folder`: the command writes (or reads) a whole folder there, so a
// path inside it is part of it too. Empty paths are ignored.
struct PathUse {
  std::string option;
  std::string path;
  bool folder = false;
};

// Throws nbtf::Error naming both options and paths when an output is the same file as an input
// or as another output, or when a folder output holds (or lies inside) an input or another
// output. Devices and pipes (/dev/stdout, a FIFO) are written in place and never clash.
void refuseOverlappingPaths(const std::vector<PathUse>& inputs, const std::vector<PathUse>& outputs);

// True when the two paths name the same file or folder (same rules as above).
bool samePath(const std::string& a, const std::string& b);

}  // namespace nbtf
