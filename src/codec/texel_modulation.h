// Per-texel modulation (beyond the paper): the decoder outputs R RGB terms per cluster,
// f_1..f_R(z_c, light, view), and each texel mixes them with coefficients of its own:
//   value(t, image) = sum_r e_tr f_r(z_c, light, view).
// With R = 1 that is a per-texel brightness factor; larger R is a per-cluster rank-R model.
// With `channels` 3 (format 1.5) each texel has its own coefficient per term and RGB channel,
// value_c(t, image) = sum_r e_trc f_rc(...): with R = 1 a per-texel colour factor. Coefficient
// arrays are texels x columns, term r and channel c at column r x channels + c (c = 0 with one
// channel).
// Training uses coefficients from the data (an SVD per cluster, cluster/cluster_values.h)
// made orthonormal per cluster (sum_{t in c} e_tr e_tr' = n_c delta_rr'), which makes the
// trainer's per-cluster targets exact (model/training_set.h). After training the pipeline
// refits every texel's coefficients to the trained terms by least squares and stores those
// as `bits`-bit linear codes per term (TexelModulation in nbtf_file.h); decoding uses the
// dequantized codes as they are.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "codec/nbtf_file.h"

namespace nbtf {

// How quantizeTexelCoefficients codes the coefficients.
enum class ModulationCodes {
  // `bits`-bit linear codes over each column's range.
  Linear,
  // Channels 3 only (format 1.11): each term's colour factor in its principal axes over the
  // texels (decorrelated columns), every column at the step that `bits`-bit linear codes give
  // the term's channels on average. The error is about that of linear codes; the bytes fall
  // with the channels' correlation. The stored code width is what the widest column needs.
  Decorrelated,
};

// Quantizes coefficients (texels x columns, texel-major) to codes over each column's range:
// its 0.1% to 99.9% quantiles (min to max below 1000 texels; values below are clamped, and
// above too with linear codes). Throws on non-finite input or out-of-range terms / bits /
// channels, and on decorrelated codes with one channel.
TexelModulation quantizeTexelCoefficients(const std::vector<float>& coefficients, int terms, int bits,
                                          int channels = 1, ModulationCodes codes = ModulationCodes::Linear);

// The eigenvectors of a symmetric 3 x 3 matrix (row-major), as the columns of an orthonormal
// matrix (row-major), ordered by decreasing eigenvalue, each with its largest entry positive.
std::array<double, 9> principalAxes3(std::array<double, 9> symmetric);

// The dequantized value of `code` in `column`: min + code / (2^bits - 1) x (max - min) (of the
// rotated column where the codes are decorrelated).
float dequantizeTexelCoefficient(const TexelModulation& modulation, int column, std::uint32_t code);

// Per cluster and channel, Gram-Schmidt on the coefficient columns in term order (sums in
// double, texels in order), each column scaled to mean square 1 over the cluster; a column
// that is (nearly) a combination of the channel's earlier ones becomes 0. `ids` maps texels to
// clusters in [0, clusters).
std::vector<float> orthonormalizeTexelCoefficients(std::vector<float> coefficients, int terms,
                                                   const std::vector<std::int32_t>& ids, int clusters,
                                                   int channels = 1);

// "2 RGB terms per cluster, mixed by per-texel coefficients (one per channel, 6-bit codes)":
// what `info` and eval reports say about a file's modulation.
std::string modulationDescription(const TexelModulation& modulation);

// What decoding multiplies the terms by: the dequantized codes (rotated back where
// decorrelated), texels x columns (empty without modulation).
std::vector<float> dequantizeTexelCoefficients(const TexelModulation& modulation);

}  // namespace nbtf
