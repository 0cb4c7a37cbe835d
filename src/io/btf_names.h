// File names of BTF image stacks. Angles are found by the tl/pl/tv/pv tokens anywhere
// in the name, so every known variant parses:
//   UBO2003:             "00008 tl000 pl000 tv030 pv030.jpg"
//   UBO2003 (prefixed):  "WoolPKNT256_00084_tl015_pl000_tv015_pv120.jpg"
//   UTIA:                "tl000_pl000_tv000_pv000.png" (or .exr)
#pragma once
#include <optional>
#include <string>

#include "io/btf_stack.h"
#include "util/directions.h"

namespace nbtf {

struct ParsedBtfName {
  Direction light, view;
  int index = -1;  // UBO2003's running image number, -1 when absent (UTIA)
  Layout layout = Layout::Unknown;  // what the name looks like
};

// Parses a file name (no folder). Returns nothing when the name has no angle tokens at all
// (an unrelated file); throws nbtf::Error when it has some but not all four, or an angle is
// out of range.
std::optional<ParsedBtfName> parseBtfFileName(const std::string& fileName);

// What a stack folder holds: image files (.jpg, .jpeg, .png, .exr; never hidden files, which
// include the temporaries of an interrupted atomic write) and view folders ("tv030_pv030").
bool isImageFileName(const std::string& fileName);
bool isViewFolderName(const std::string& folderName);

// The description `nbtf decode` writes into its output folder (docs/decoding.md).
inline constexpr const char* kDecodeDescriptionName = "nbtf_decode.json";
// Its staging folder beside the output: "." + the output's name + this suffix
// (pipeline/decode_folder.h). Such a folder is always an unfinished decode.
inline constexpr const char* kDecodeStagingSuffix = ".nbtf-decoding";

// The names nbtf writes (and the loaders read), for image (light, view).
std::string viewFolderName(const Direction& view);  // "tv030_pv030"
std::string ubo2003FileName(int index, const Direction& light, const Direction& view, const std::string& ext);
std::string utiaFileName(const Direction& light, const Direction& view, const std::string& ext);

}  // namespace nbtf
