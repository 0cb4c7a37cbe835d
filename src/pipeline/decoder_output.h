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
#include "preprocess/ubo2014_factorize.h"

namespace nbtf {

// A light or view to decode: a measured direction (index into the material's list) or
// any other direction on the hemisphere (index -1).
struct DirectionChoice {
  Direction direction;
  int index = -1;
  bool measured() const { return index >= 0; }
};

// Parses a --lights / --views LIST (`option` names it in errors):
//   all                 every measured direction (the default)
//   ITEM[,ITEM...]      items in the order given, duplicates removed
//   ITEM = N            measured direction number N (0-based, in the order the loader sorts
//                       them: theta ascending, then phi; 0..80 for the 81-direction sets)
//        | N-M          measured directions N to M inclusive
//        | tTHETApPHI   the direction (THETA, PHI) in degrees, e.g. t37.5p200; a measured
//                       direction when it is one (to 1e-6 degrees), else unmeasured
std::vector<DirectionChoice> parseDirectionList(const std::string& text, const std::vector<Direction>& measured,
                                                const std::string& option);
// One direction as THETA,PHI degrees (for --light / --view), matched to a measured one when equal.
DirectionChoice chooseDirection(const Direction& d, const std::vector<Direction>& measured);
std::vector<DirectionChoice> allDirections(const std::vector<Direction>& measured);

// "WxH" -> (width, height), both in 1..maxSide; throws naming `option`.
std::pair<int, int> parseImageSize(const std::string& text, const std::string& option, int maxSide = 1 << 16);

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
// Path of one image relative to the output folder. One naming per layout: UBO2003 names
// carry a running number, the source's image number (light x views + view) when both
// directions are measured, else `outputIndex` (the decode numbers all of its images by their
// position in the output whenever one of them is unmeasured, so numbers never collide).
std::string decodedImagePath(Layout layout, ImageFormat format, const DirectionChoice& light,
                             const DirectionChoice& view, int numViews, int outputIndex = -1);

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

// linearToSrgb8 (io/color.h), bit-exact, without a pow() per value: a table indexed by the
// float's bit pattern gives the code at the start of the value's bucket (2^13 neighbouring
// floats, a relative width of 1e-3, narrower than any gap between two rounding thresholds),
// and one comparison with the next threshold finishes it. Modulated materials encode every
// texel of every decoded image (65.6 million values for a 100 x 100 x 6561 stack), so this
// is on the decoder's critical path.
class Srgb8Encoder {
 public:
  Srgb8Encoder();
  std::uint8_t operator()(float linear) const {
    if (!(linear > 0)) return 0;  // also NaN, like linearToSrgb8
    if (linear >= 1.0f) return 255;
    std::uint32_t bits;
    std::memcpy(&bits, &linear, sizeof bits);
    if (bits < firstBits_) return 0;
    const int code = bucketCode_[(bits - firstBits_) >> kBucketShift];
    return static_cast<std::uint8_t>(code + (linear >= thresholds_[code]));
  }

 private:
  static constexpr int kBucketShift = 13;
  float thresholds_[256];                  // smallest linear value that encodes to i + 1; [255] = +inf
  std::uint32_t firstBits_ = 0;            // bit pattern of thresholds_[0]
  std::vector<std::uint8_t> bucketCode_;  // code of each bucket's first float
};

}  // namespace nbtf
