// Making a UBO2014 (DFMF) material from images: decorrelate the colours, then factorize
// each channel's matrix (light/view pairs x texels) by a truncated SVD, as Bonn's format
// stores it (U with one row per light/view pair, SxV = V S with one row per texel).
//
// The SVD is randomized (range finder with power iterations, Halko et al.); with at least
// as many columns in the sketch as the matrix's smaller side it is exact up to rounding.
// Memory: the three channel matrices in float32, pairs x texels x 12 bytes (e.g. 22,801
// images of 32 x 32 texels: 280 MB), besides the caller's images.
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
};

struct Ubo2014FactorizeReport {
  double rmseLinear = 0;     // linear RGB, decoded factors (as stored) vs the input, over every value
  double maxAbsError = 0;
  double inputMean = 0;      // mean linear value of the input
  int components = 0;        // per channel, as stored
  double seconds = 0;
};

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
