// The output folder of `nbtf decode`, replaced as a whole or not at all. The images go into a
// new hidden folder beside the destination (".NAME.nbtf-decoding"), whose description
// (io/btf_names.h kDecodeDescriptionName) says "complete": false until the last image is
// written, so every loader refuses it; then it is marked complete and exchanged with the
// destination in one rename. A decode killed at any moment leaves the earlier decode whole,
// or the new one whole, never the two mixed. Only a new folder, an empty one or an earlier nbtf
// decode (which holds nothing but its own images) is accepted as the destination: a measured
// stack or anything else nbtf did not write is refused before any work.
#pragma once
#include <string>
#include <system_error>

namespace nbtf {

class DecodeFolder {
 public:
  // Checks `destination`, removes a staging folder an interrupted decode left there, and
  // creates the staging folder with its description (`descriptionJson`, an object, gets
  // "complete": false). Throws nbtf::Error naming the folder and the reason.
  DecodeFolder(const std::string& destination, const std::string& descriptionJson);
  ~DecodeFolder();  // not committed (an error was thrown): removes the staging folder
  DecodeFolder(const DecodeFolder&) = delete;
  DecodeFolder& operator=(const DecodeFolder&) = delete;

  // Where the images go until commit().
  const std::string& staging() const { return staging_; }
  // Marks the description complete and puts the staging folder in the destination's place;
  // an earlier decode there is removed.
  void commit();

 private:
  std::string destination_, staging_, description_;
  bool committed_ = false;
};

// Throws nbtf::Error when `folder` (which exists) is not a folder nbtf decode may replace: one
// holding a measured stack or any file nbtf decode did not write. Named in the error: the first
// such entry.
void checkReplaceableDecodeFolder(const std::string& folder);

// Removes a folder nbtf decode wrote (a staging folder, an earlier decode): its description is
// first marked `"complete": false`, then the images go, then the description, so a removal
// killed half-way leaves a folder that the next decode still recognises as its own and that
// no loader takes for a complete decode. An error lands in `ec` and stops the removal there.
void removeDecodeFolder(const std::string& folder, std::error_code& ec);

}  // namespace nbtf
