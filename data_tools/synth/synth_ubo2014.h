// A synthetic material written as a Bonn UBO2014 `.btf` file (DFMF, io/ubo2014_btf.h): the
// material rendered under the 151 x 151 Dome 1 directions, its colours decorrelated and each
// channel factorized by a truncated SVD (preprocess/ubo2014_factorize.h), factors stored as half floats.
#pragma once
#include <string>

#include "preprocess/ubo2014_factorize.h"
#include "synth/synth_material.h"

namespace nbtf::synth {

struct SynthUbo2014Summary {
  int images = 0;                        // rendered light/view pairs (22,801)
  Ubo2014FactorizeReport factorization;  // the stored factors vs the rendered values
  std::size_t fileBytes = 0;
  double seconds = 0;
};

// Renders options' material (layout and format are not used) and writes `path` atomically.
// Memory: the three channel matrices, 22,801 x texels x 12 bytes (280 MB at 32 x 32), held
// up to factorize.memoryLimit; above it streamed (rendered again for each pass), and then
// about the shadow passes, 302 x fine samples x 8 bytes (1.2 GB at 400 x 400, supersampling 2).
SynthUbo2014Summary writeSynthUbo2014(const SynthOptions& options, const std::string& path,
                                      const Ubo2014FactorizeOptions& factorize);

}  // namespace nbtf::synth
