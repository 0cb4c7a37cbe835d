// Making a UBO2014 (DFMF) material from images: decorrelate the colours, then factorize
// each channel's matrix (light/view pairs x texels) by a truncated SVD, as Bonn's format
// stores it (U with one row per light/view pair, SxV = V S with one row per texel).
//
// The SVD is randomized (range finder with power iterations, Halko et al.); with at least
// as many columns in the sketch as the matrix's smaller side it is exact up to rounding.
// Memory: the three channel matrices in float32, pairs x texels x 12 bytes (e.g. 22,801
// images of 32 x 32 texels: 280 MB), besides the caller's images; or, above
// Ubo2014FactorizeOptions::memoryLimit, streamed: blocks of about 64 MB of images and the
// sketches (texels x (components + oversampling) x 12 bytes, a few times).
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "io/btf_stack.h"
#include "io/ubo2014_btf.h"

namespace nbtf {

struct Ubo2014FactorizeOptions {
  int components = 32;       // per channel (fewer when the matrix is smaller)
  std::int32_t colorModel = 11;  // 11 (Ylog, U/Y, V/Y) or 0 (RGB); see docs/ubo2014.md
  int scalarSize = 2;        // 2: half floats, as Bonn's writer stores them
  int oversampling = 10;
  int powerIterations = 2;
  std::uint64_t seed = 1;
  bool progress = true;
  std::string xml;           // stored in the header's XML field (a description of the source)
  // The channel matrices (ubo2014MatrixBytes) are held in memory up to this size (0: half of
  // defaultMemoryLimit()). Above it nothing of that size is held: every pass of the SVD asks
  // for the images again, 2 + 2 x powerIterations passes, and one more for the report.
  std::size_t memoryLimit = 0;
  std::size_t blockBytes = std::size_t{64} << 20;  // images made at a time, about this many bytes
};

struct Ubo2014FactorizeReport {
  double rmseLinear = 0;     // linear RGB, decoded factors (as stored) vs the input, over every value
  double maxAbsError = 0;
  double inputMean = 0;      // mean linear value of the input
  int components = 0;        // per channel, as stored
  double seconds = 0;
  bool streamed = false;     // the images were asked for once per pass instead of held
  int passes = 1;            // times each image was asked for
};

// Bytes of the three channel matrices in float32: images x texels x 12.
std::size_t ubo2014MatrixBytes(int images, int texels);

// Throws nbtf::Error for options the writer cannot use (colour model, components, scalar
// size): callers check before rendering or decoding anything.
void checkUbo2014FactorizeOptions(const Ubo2014FactorizeOptions& options);

// `image(i, rgb)` fills image i = light * views + view (width * height * 3 linear floats,
// texel y * width + x). Throws nbtf::Error for a colour model it cannot write or a negative
// value under a logarithmic model.
Ubo2014Btf factorizeUbo2014(const std::vector<Direction>& lights, const std::vector<Direction>& views, int width,
                            int height, const std::function<void(int, float*)>& image,
                            const Ubo2014FactorizeOptions& options, Ubo2014FactorizeReport* report = nullptr);

// The same from a stack in memory.
Ubo2014Btf factorizeUbo2014(const BtfStack& stack, const Ubo2014FactorizeOptions& options,
                            Ubo2014FactorizeReport* report = nullptr);

}  // namespace nbtf
