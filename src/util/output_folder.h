// An output folder written as a whole or not at all (the shader export, the glTF export): the
// files go into a hidden temporary folder beside the destination, which then takes the
// destination's place in renames; a failure or a kill before then leaves the destination as
// it was. Only a new folder, an empty one, or one the same command wrote (`isOurs`) is
// replaced: anything else is refused before any work.
#pragma once
#include <filesystem>
#include <functional>
#include <string>

namespace nbtf {

struct OutputFolderKind {
  std::string what;  // "a shader export", "a glTF export": in messages
  std::string marker;  // the file every such folder holds (manifest.json, material.gltf)
  // Whether a folder holding `marker` is one of ours (default: holding it is enough).
  std::function<bool(const std::filesystem::path& folder)> isOurs;
};

// Throws nbtf::Error naming `dir` when it exists and is neither empty nor one of `kind`'s.
void checkReplaceableFolder(const std::string& dir, const OutputFolderKind& kind);

// Checks `dir`, then calls write(temporaryFolder) and puts that folder in `dir`'s place.
// On any error the temporary folder is removed and the error rethrown (a filesystem error as
// nbtf::Error naming `dir`).
void writeFolderAtomic(const std::string& dir, const OutputFolderKind& kind,
                       const std::function<void(const std::filesystem::path& folder)>& write);

// Writes `size` bytes to `path` (inside a folder being written: no rename of its own).
void writeWholeFile(const std::filesystem::path& path, const void* data, std::size_t size);

}  // namespace nbtf
