// The classic PCA baseline of BTF compression, behind `nbtf compress --method pca`:
// every texel's ABRDF (N images x RGB, linear values / alpha, the same alpha as the neural
// methods, so its RMSE is eq. (10) too) is approximated by the mean ABRDF plus C principal
// components: the file stores the mean (3N floats), the basis (3N x C) and per-texel
// coefficients (texels x C). See codec/pca_model.h for the evaluation and the interpolation
// at unmeasured directions.
//
// With a hold-out fraction the held-out images are chosen exactly as the neural methods
// choose them (the trainer's TrainingSet, same seed -> same images) and left out of the PCA
// fit; their mean and basis rows are then interpolated from the fitted images like any
// unmeasured direction, so the hold-out RMSE measures interpolation, as for the neural
// methods.
#pragma once
#include "pipeline/compressor.h"

namespace nbtf {

// The PCA part of compressStack (options.pcaBaseline): fills `stats` (RMSE on the fitted and
// held-out images, measured by decoding the result exactly as `nbtf eval` does; sizes;
// seconds.preprocess and seconds.pca). Throws nbtf::Error for components outside
// [1, min(texels, 3 x fitted images)].
CompressedBtf compressPcaStack(const BtfStack& stack, const CompressOptions& options, CompressStats& stats);

// The largest component count the PCA baseline accepts for this many texels and images
// (after the hold-out images are removed).
int maxPcaComponents(std::int64_t texels, std::int64_t fittedImages);

}  // namespace nbtf
