// PCA by randomized SVD (range finder + power iterations): cost O(M * D * (C + p)),
// never a dense D x D matrix.
#pragma once
#include <Eigen/Core>
#include <cstddef>
#include <cstdint>

#include "preprocess/abrdf_source.h"

namespace nbtf {

// Cost is 2 * powerIterations + 2 product passes over X (+ 1 for the column statistics); a
// wide sketch is cheaper than more passes (a pass costs little more at 80 columns than at
// 42). On a synthetic fabric (32 components, 93.3% explained), the explained variance falls
// short of the exact PCA's by 1.5e-4 of itself with these defaults (4 passes), 6e-5 with 4
// iterations and oversampling 10 (10 passes): far below what changes a clustering. Raise
// powerIterations for flat spectra.
//
// Large materials (at least 4 x sampleRows(D) texels) find the sketch's subspace on a random
// sample of texels held in memory (AbrdfSource::gatherRows: a stack reads, or computes, only
// those texels), then project every texel onto that subspace in one product pass and take the
// SVD within it from all of X: 2 passes over X instead of 2 * powerIterations + 2, and scores
// that are exactly (X - mean) * basis. Why: on a full material the passes are most of the
// clustering stage (docs/clustering.md, *PCA*).
struct PcaOptions {
  int components = 32;
  int oversampling = 48;
  int powerIterations = 1;
  std::uint64_t seed = 1;
  bool progress = true;
  // Memory for the sample (floats); 0: every texel in every pass, at any size.
  std::size_t sampleBytes = std::size_t(256) << 20;
  // The sample for D dimensions: sampleBytes of float rows, between 2048 and 16384 texels.
  Eigen::Index sampleRows(Eigen::Index dims) const;
  // Whether a PCA of rows x dims samples (sampleBytes > 0, rows >= 4 x sampleRows(dims), and
  // the sample at least twice the sketch, components + oversampling).
  bool samples(Eigen::Index rows, Eigen::Index dims) const;
};

struct PcaResult {
  Eigen::VectorXf mean;          // D: column means subtracted before the SVD
  MatrixXfCol basis;             // D x C, orthonormal columns
  MatrixXfCol scores;            // M x C: (X - mean) * basis (computed as the SVD's U * S, which
                                 // equals it up to the part of X the sketch did not capture)
  Eigen::VectorXf explainedVariance;  // C: variance along each component
  double totalVariance = 0;      // sum of the variances of all D dimensions
  Eigen::Index sampledTexels = 0;  // texels the subspace was found on (0: all of them)
  double explainedRatio() const; // sum(explainedVariance) / totalVariance
};

// Throws nbtf::Error if components < 1 or components > min(M, D). X comes from `x` in slices
// (preprocess/abrdf_source.h): 2 * powerIterations + 3 reads (3 when sampling), never a copy
// of X. An in-memory X and a stack give the same bits.
PcaResult randomizedPca(const AbrdfSource& x, const PcaOptions& options);
PcaResult randomizedPca(const MatrixXfCol& x, const PcaOptions& options);

}  // namespace nbtf
