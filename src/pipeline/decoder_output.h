// Decoding a material back into an image stack: on disk in the layout and naming the
// loaders read (what `nbtf decode` writes), or in memory as a BtfStack. Which images:
// every measured (light, view) pair, a subset, or directions that were never measured.
//
// Files: one folder per view (tvTTT_pvPPP/), as both data sets ship. UBO2003 names carry
// the running index light * views + view ("00008 tl000 pl000 tv030 pv030.png"); UTIA names
// are angles only ("tl000_pl000_tv000_pv000.png"). An image at an unmeasured light or view
// has no index, so it gets the angle-only name in either layout (angles with decimals
// are written as e.g. "tl037.500"). PNG/JPG hold 8-bit sRGB; EXR holds linear half floats,
// un-normalized (decoder output x alpha): linear sRGB for the UBO2003 layout, CIE XYZ with
// XYZ chromaticities for the UTIA layout (as the UTIA database stores its EXRs; the loader
// converts both back). Negative network outputs are clamped to 0 in every file format (the
// loaders reject negative EXR values); the count is reported.
#pragma once
#include <atomic>
#include <cstdint>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "codec/decoder.h"
#include "io/btf_stack.h"
#include "io/image_io.h"
#include "pipeline/decode_selection.h"
#include "preprocess/ubo2014_factorize.h"

namespace nbtf {


struct DecodeStackOptions {
  Layout layout = Layout::Unknown;  // Unknown: the material's source layout (UBO2003 if unknown)
  std::optional<ImageFormat> format;  // default: EXR for half-float sources, else PNG
  std::vector<DirectionChoice> lights, views;  // empty = every measured direction
  int width = 0, height = 0;  // output image size; 0 = the material's (larger sizes tile it)
  int jpegQuality = 95;
  bool progress = true;
  // Set (Ctrl-C): no further image is started; the staging folder is removed, nothing is
  // written to the destination and the result says `interrupted`.
  const std::atomic<bool>* stopFlag = nullptr;
};

struct DecodeStackResult {
  std::string folder;
  Layout layout = Layout::Unknown;
  ImageFormat format = ImageFormat::Png;
  int lights = 0, views = 0, images = 0;
  int width = 0, height = 0;
  std::uint64_t evaluations = 0;      // decoder evaluations (latentRows per image)
  std::uint64_t clampedNegative = 0;  // linear values < 0 written as 0
  double seconds = 0;
  bool interrupted = false;  // stopFlag was set: `written` of `images` were written, then removed
  int written = 0;
};

// The layout and format the options resolve to for this material.
Layout resolvedLayout(const NbtfDecoder& decoder, const DecodeStackOptions& options);
ImageFormat resolvedFormat(const NbtfDecoder& decoder, const DecodeStackOptions& options);

// Decodes every selected (light, view) pair into `folder` (created if missing), in
// parallel on threadCount() threads, each file written atomically.
DecodeStackResult writeDecodedStack(const NbtfDecoder& decoder, const std::string& folder,
                                    const DecodeStackOptions& options);
std::string formatDecodeSummary(const DecodeStackResult& result, const NbtfDecoder& decoder);

// `nbtf decode --layout ubo2014`: the selected images decoded into a half-float stack in
// memory (texels x images x 6 bytes), factorized per colour channel (preprocess/ubo2014_factorize.h)
// and written as one UBO2014 .btf file (atomically) that Bonn's reader and nbtf's loader read.
struct DecodeUbo2014Result {
  std::string file;
  int lights = 0, views = 0, images = 0, width = 0, height = 0;
  std::size_t fileBytes = 0;
  Ubo2014FactorizeReport factorization;  // stored factors vs the decoded values
  double seconds = 0;
};
DecodeUbo2014Result writeDecodedUbo2014(const NbtfDecoder& decoder, const std::string& path,
                                        const DecodeStackOptions& options, const Ubo2014FactorizeOptions& factorize);
std::string formatDecodeUbo2014Summary(const DecodeUbo2014Result& result);

// The same images in memory, as the loader would return them: 8-bit sRGB or half float
// (linear), lights x views in the order given (empty = all measured), the material's size.
BtfStack decodeStack(const NbtfDecoder& decoder, SampleType type, const std::vector<DirectionChoice>& lights = {},
                     const std::vector<DirectionChoice>& views = {}, bool progress = true);

}  // namespace nbtf
