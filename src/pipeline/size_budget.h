// --size-budget without --adaptive: the largest k (PCA: the components) whose file fits a byte
// budget and, without --config, the named config of the curve (docs/model.md, *Which config
// for which file*) that the budget reaches. Chosen after the input is resolved and before it is
// loaded, by writing the material's skeleton: every part at the shape the run will give it,
// the parts whose content only the run knows (the ids, the per-texel codes) drawn at random, as
// little compressible as theirs can be, and the run's metadata allowed for. The estimate is an
// upper bound of the file the run writes.
#pragma once
#include <cstdint>

#include "io/btf_loader.h"
#include "pipeline/compressor.h"

namespace nbtf {

// The densest point measured: configs/close_up.json's one cluster per 2.5 texels. A budget never
// gives more clusters than this (more would train minutes longer for clusters of two texels).
constexpr double kDensestTexelsPerCluster = 2.5;

// An upper bound of the bytes of the .nbtf that `o` writes for `in` with `count` clusters (PCA:
// components); o.clusters and o.pcaComponents are not read.
std::uint64_t estimatedFileBytes(const BtfInput& in, const CompressOptions& o, int count);

// With o.sizeBudget: the recipe (o.sizeBudgetCurve's largest whose takeover point fits, else
// its first; without a curve o's own)
// and the largest k or C in it whose estimate fits, set in `o` and recorded in `stats`. Throws
// nbtf::Error naming the smallest file the input allows when the budget is below it, and for a
// method without a count to choose (per-texel).
void chooseSizeBudgetPoint(const BtfInput& in, CompressOptions& o, CompressStats& stats);

}  // namespace nbtf
