// The compressor of the two neural kinds (codec/methods/clustered.cpp, per_texel.cpp): the
// standardization, the clustering (or, per texel, the standardized matrix itself), the
// per-texel modulation coefficients, training, and the assembly into a material. Adaptive
// clusters (pipeline/adaptive.h) take over after the first clustering: a way to train the
// clustered kind. PRIVATE to src/pipeline.
#pragma once
#include <cstdint>
#include <string>

#include "pipeline/compressor.h"

namespace nbtf::detail {

// Clustered (options.clusters > 0) or per-texel (0). Fills `stats` as compressStack says.
CompressedBtf compressNeuralStack(const BtfStack& stack, const CompressOptions& options, CompressStats& stats);

// A default k becomes the input's (defaultClusterCount); the stats keep the configured one when
// the input capped it.
void resolveDefaultClusters(CompressOptions& o, std::int64_t texels, CompressStats& stats);
// k and, with adaptive clusters, its cap: both at most the texel count (`what` names the input).
void checkClusterCounts(const CompressOptions& o, std::int64_t texels, const std::string& what);

}  // namespace nbtf::detail
