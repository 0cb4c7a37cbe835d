// Loading UBO2003 and UTIA image stacks from disk, and UBO2014 `.btf` files (io/ubo2014_btf.h):
// every function here takes a `.btf` file path where it takes a stack folder.
#pragma once
#include <memory>
#include <string>

#include "io/btf_stack.h"

namespace nbtf {

class Ubo2014Btf;

struct LoadOptions {
  Layout layout = Layout::Unknown;  // Unknown = detect from the file names
  Crop crop;                        // applied while decoding: cropped-out texels never take memory
  bool progress = true;             // progress bar on the terminal
  // EXR colour space when the file does not say: UTIA EXRs are CIE XYZ (D65).
  bool utiaExrIsXyz = true;
  // A UBO2014 file's crop is expanded into a half-float stack (fast to read) when that takes
  // at most this many bytes; a larger one stays factorized, its values computed when read
  // (BtfStack::isComputed: the same values, memory of the factors only).
  std::size_t expandUpTo = kExpandUpToDefault;
  static constexpr std::size_t kExpandUpToDefault = std::size_t(2) << 30;
  // Non-empty: an image stack's samples go to a scratch file in this folder instead of memory
  // (BtfStack::inScratchFile; the same values, the pages held by the system's file cache).
  std::string scratchDir;
};

// Finds the images of a stack under `path`: either a folder per view (tvTTT_pvPPP/) or a
// flat folder of images. Files without image extensions and subfolders not named like
// view folders are ignored (so ground truth and notes can sit beside the stack).
struct StackFile {
  std::string path;
  Direction light, view;
  int index = -1;
};
struct StackListing {
  Layout layout = Layout::Unknown;
  std::vector<Direction> lights, views;  // sorted: theta ascending, then phi
  std::vector<std::string> files;        // files[light * views + view]
};
StackListing listBtfStack(const std::string& path, Layout forced = Layout::Unknown);

// The shape a load would give (crop applied), from the listing and the first image only
// (a UBO2014 file: its header and factors): what memory estimates need before loading.
struct StackShape {
  int lights = 0, views = 0, width = 0, height = 0;
  SampleType type = SampleType::Srgb8;
  std::size_t computedBytes = 0;  // > 0: a factorized UBO2014 stack, values computed from factors of this size
  std::int64_t texels() const { return static_cast<std::int64_t>(width) * height; }
  int images() const { return lights * views; }
  // Bytes of the values, stored (8-bit sRGB: 1 byte per value, half: 2) or computed.
  std::size_t storedBytes() const {
    return static_cast<std::size_t>(images()) * static_cast<std::size_t>(texels()) * 3 * (type == SampleType::Srgb8 ? 1 : 2);
  }
  std::size_t stackBytes() const { return computedBytes ? computedBytes : storedBytes(); }
};

// An input resolved once: what it is, its directions and files, the crop checked against its
// images, the shape a load gives, and (a UBO2014 file) its factors, read once and whether they
// stay factorized. The memory estimate, the loader and the compressor all take this one
// description, so the input is listed, its first image read and its crop checked once.
struct BtfInput {
  std::string path;
  StackListing listing;                       // layout, directions; files of an image stack
  int sourceWidth = 0, sourceHeight = 0;      // the images' size on disk
  Crop crop;                                  // checked; the whole image when none was asked
  bool cropped = false;                       // a crop was asked (the stack records it)
  StackShape shape;
  std::shared_ptr<const Ubo2014Btf> ubo2014;  // a UBO2014 file's factors; null for an image stack
  bool factorized = false;                    // UBO2014: the crop's values computed when read (LoadOptions::expandUpTo)
};
// Lists the input and reads its first image (a UBO2014 file: its header and factors): throws the
// loader's errors, a crop outside the images included, before a long load.
BtfInput resolveBtfInput(const std::string& path, const LoadOptions& options = {});

// Loads the whole stack (decoding in parallel on threadCount() threads). Throws nbtf::Error
// naming the file and the problem for every kind of bad input. `options` gives the scratch
// folder and the progress bar; the rest was decided when the input was resolved.
BtfStack loadBtfStack(const BtfInput& input, const LoadOptions& options = {});
// The same from a path (resolved here).
BtfStack loadBtfStack(const std::string& path, const LoadOptions& options = {});

// resolveBtfInput(path, options).shape and .crop, for callers that need one of them only.
StackShape stackShape(const std::string& path, const LoadOptions& options = {});
Crop checkCrop(const std::string& path, const LoadOptions& options);

}  // namespace nbtf
