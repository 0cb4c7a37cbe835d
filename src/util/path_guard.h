// Refusing, before any work, an output that would overwrite one of the command's inputs or
// another of its outputs. Every command and the Python module declare what they read and
// write as PathUses and call refuseOverlappingPaths once, before anything is read or created.
//
// Paths are compared as the file system sees them: through symbolic links and `..` (the
// canonical path; a `..` after a folder that does not exist yet is resolved as the folder
// would be once created), and by device and inode where the file exists, so a hard link or a
// bind mount of an input is caught too. An input that is a folder (an image stack, a ground
// truth folder, a report folder) is its whole tree: no output may lie anywhere inside it.
#pragma once
#include <string>
#include <vector>

namespace nbtf {

// One path a command reads or writes, with the option that named it ("-o", "--stats-json",
// "<input>") for the error. Outputs: `folder` when the command writes a whole folder there, so
// a path inside it is part of it too. Inputs: a folder is found out from the file system
// (through links), whatever `folder` says. Empty paths are ignored.
struct PathUse {
  std::string option;
  std::string path;
  bool folder = false;
};

// Throws nbtf::Error naming both options and paths when an output is the same file as an
// input or as another output, lies inside an input folder or an output folder, or is a folder
// that holds an input or another output. Devices and pipes (/dev/stdout, a FIFO) are written
// in place and never clash. Creates nothing.
void refuseOverlappingPaths(const std::vector<PathUse>& inputs, const std::vector<PathUse>& outputs);

// True when the two paths name the same file or folder (same rules as above).
bool samePath(const std::string& a, const std::string& b);

}  // namespace nbtf
