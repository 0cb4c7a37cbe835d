#include "pipeline/decode_folder.h"

#include <stdio.h>
#include <fcntl.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <vector>

#include "io/btf_names.h"
#include "util/atomic_file.h"
#include "util/error.h"

namespace nbtf {
namespace fs = std::filesystem;

namespace {

bool hasDescription(const fs::path& folder) {
  std::error_code ec;
  return fs::is_regular_file(folder / kDecodeDescriptionName, ec);
}

std::string refusal(const fs::path& entry, const std::string& what) {
  return "holds " + what + " that nbtf decode did not write ('" + entry.string() +
         "'); decode into a new or empty folder (nbtf decode replaces only its own earlier decodes)";
}

// The first entry of `folder` that an nbtf decode would not have written, or "".
std::string foreignEntry(const fs::path& folder) {
  std::error_code ec;
  const bool ours = hasDescription(folder);
  for (const auto& e : fs::directory_iterator(folder, ec)) {
    const std::string name = e.path().filename().string();
    if (ours && name == kDecodeDescriptionName) continue;
    const bool dir = e.is_directory(ec);
    if (!ours) {
      // A stack is the worst case to overwrite: say so.
      bool stack = dir ? isViewFolderName(name) : (isImageFileName(name) && parseBtfFileName(name).has_value());
      return refusal(e.path(), stack ? "a BTF image stack" : "files");
    }
    if (!dir || !isViewFolderName(name)) return refusal(e.path(), "a file");
    for (const auto& inner : fs::directory_iterator(e.path(), ec)) {
      const std::string innerName = inner.path().filename().string();
      const bool temporary = innerName.size() > 1 && innerName[0] == '.' && innerName.find(".tmp") != std::string::npos;
      if (!temporary && !(inner.is_regular_file(ec) && isImageFileName(innerName)))
        return refusal(inner.path(), "a file");
    }
  }
  if (ec) return "cannot be listed: " + ec.message();
  return "";
}

// Exchanges two folders in one step (Linux renameat2 RENAME_EXCHANGE); false where the file
// system cannot, and the caller falls back to two renames.
bool exchangeFolders(const std::string& a, const std::string& b) {
#ifdef RENAME_EXCHANGE
  return ::renameat2(AT_FDCWD, a.c_str(), AT_FDCWD, b.c_str(), RENAME_EXCHANGE) == 0;
#else
  (void)a, (void)b;
  return false;
#endif
}

// A staging folder killed between its creation and its description's atomic write: empty, or
// holding only that write's temporary file (".nbtf_decode.json.tmp...").
bool describedNotYet(const fs::path& folder) {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(folder, ec))
    if (!isTemporaryNameFor(e.path().filename().string(), kDecodeDescriptionName)) return false;
  return !ec;
}

void writeDescription(const std::string& folder, nlohmann::json description, bool complete) {
  description["complete"] = complete;
  writeFileAtomic((fs::path(folder) / kDecodeDescriptionName).string(), description.dump(2) + "\n");
}

}  // namespace

void removeDecodeFolder(const std::string& folderText, std::error_code& ec) {
  const fs::path folder(folderText);
  if (hasDescription(folder)) {
    try {
      std::ifstream in(folder / kDecodeDescriptionName);
      nlohmann::json d = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
      if (d.is_object() && d.value("complete", false)) writeDescription(folder.string(), d, false);
    } catch (const std::exception&) {
      // An unwritable description is removed with the rest all the same.
    }
  }
  std::vector<fs::path> entries;
  for (const auto& e : fs::directory_iterator(folder, ec))
    if (e.path().filename() != kDecodeDescriptionName) entries.push_back(e.path());
  for (const fs::path& e : entries) {
    fs::remove_all(e, ec);
    if (ec) return;  // the description stays (incomplete) while anything else does
  }
  fs::remove_all(folder, ec);
}

void checkReplaceableDecodeFolder(const std::string& folder) {
  const std::string why = foreignEntry(folder);
  if (!why.empty()) throw fileError(folder, why);
}

DecodeFolder::DecodeFolder(const std::string& destination, const std::string& descriptionJson) {
  std::error_code ec;
  // Through a symbolic link to the folder it names (the link stays a link).
  destination_ = fs::weakly_canonical(fs::absolute(destination), ec).string();
  if (ec || destination_.empty()) destination_ = fs::absolute(destination).lexically_normal().string();
  const fs::path dest(destination_);
  if (fs::exists(dest, ec)) {
    if (!fs::is_directory(dest, ec)) throw fileError(destination, "exists and is not a folder");
    checkReplaceableDecodeFolder(destination);
  }
  if (!dest.has_filename() || dest == dest.root_path()) throw fileError(destination, "cannot replace this folder");
  fs::create_directories(dest.parent_path(), ec);
  if (ec) throw fileError(destination, "cannot create the folder '" + dest.parent_path().string() + "': " + ec.message());
  staging_ = (dest.parent_path() / ("." + dest.filename().string() + kDecodeStagingSuffix)).string();
  if (fs::exists(staging_, ec)) {
    // Left by a decode that was killed: ours if it has our description (or was killed before
    // writing it).
    const bool ours = fs::is_directory(staging_, ec) &&
                      ((hasDescription(staging_) && foreignEntry(staging_).empty()) || describedNotYet(staging_));
    if (!ours)
      throw fileError(staging_, "is in the way of the decode's staging folder and was not written by nbtf decode; "
                                "remove it or choose another output folder");
    removeDecodeFolder(staging_, ec);
    if (ec) throw fileError(staging_, "cannot remove an interrupted decode: " + ec.message());
  }
  fs::create_directory(staging_, ec);
  if (ec) throw fileError(destination, "cannot create the staging folder '" + staging_ + "': " + ec.message());
  try {
    description_ = descriptionJson;
    writeDescription(staging_, nlohmann::json::parse(description_), false);
  } catch (...) {
    removeDecodeFolder(staging_, ec);
    throw;
  }
}

DecodeFolder::~DecodeFolder() {
  if (committed_) return;
  std::error_code ec;
  removeDecodeFolder(staging_, ec);
}

void DecodeFolder::commit() {
  writeDescription(staging_, nlohmann::json::parse(description_), true);
  std::error_code ec;
  if (!fs::exists(destination_, ec)) {
    if (std::rename(staging_.c_str(), destination_.c_str()) != 0)
      throw fileError(destination_, std::string("cannot move the decoded folder into place: ") + std::strerror(errno));
  } else if (exchangeFolders(staging_, destination_)) {
    removeDecodeFolder(staging_, ec);  // now the earlier decode
  } else {
    // Two renames: a kill between them leaves the destination missing and both decodes whole
    // under hidden names, never a mixture.
    const std::string old = staging_ + "-old";
    removeDecodeFolder(old, ec);  // an earlier fallback's leftover, if any
    if (std::rename(destination_.c_str(), old.c_str()) != 0 || std::rename(staging_.c_str(), destination_.c_str()) != 0)
      throw fileError(destination_, std::string("cannot move the decoded folder into place: ") + std::strerror(errno));
    removeDecodeFolder(old, ec);
  }
  committed_ = true;
}

}  // namespace nbtf
