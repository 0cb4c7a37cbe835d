// What a one-latent-per-cluster model can best do, measured on the data (linear RGB / alpha):
// per cluster and image its best values, and what is left over, the floor. Without per-texel
// modulation the best value is the cluster mean and the floor is the within-cluster spread.
// With modulation (codec/texel_modulation.h) texel t's value is sum_r e_tr f_r, the
// coefficients orthonormal per cluster (sum_{t in c} e_tr e_tr' = n_c delta_rr'); the best
// terms are then T_r = sum_t e_tr y_t / n_c and the leftover sum_t |y_t - sum_r e_tr T_r|^2:
// a per-cluster projection, whose floor lies below the plain one.
// Also the coefficients themselves, derived from the data (a rank-R model per cluster).
#pragma once
#include <Eigen/Core>
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "io/btf_stack.h"

namespace nbtf {

struct ClusterValues {
  std::vector<float> means;       // clusters x images x (3 terms): term r, channel c at 3 r + c (when kept)
  std::vector<double> withinSse;  // per image: sum over texels and channels of the leftover squared
  std::vector<double> plainWithinSse;  // the same for the plain cluster means (plainFloorToo)
  // RMSE of the leftover over the given images (eq. 10: texels x images x 3), the floor.
  double floorRmse(const std::vector<int>& images, std::int64_t texels) const;
  double plainFloorRmse(const std::vector<int>& images, std::int64_t texels) const;
};

// Parallel over images; each image's sums run in texel order, so the result does not depend
// on the thread count. `coefficients`: texels x terms x channels orthonormalized coefficients
// (term r, channel c at r x channels + c; channels 3: channel c's values mix only its own), or
// nullptr (terms must be 1: plain cluster means).
// `plainFloorToo`: also the plain cluster means' leftover from the same pass (plainWithinSse).
ClusterValues clusterValues(const BtfStack& stack, float alpha, const std::vector<std::int32_t>& ids, int clusters,
                            const float* coefficients, int terms, bool keepMeans, bool progress, int channels = 1,
                            bool plainFloorToo = false);

// Per-texel coefficients of the best rank-`terms` model of each cluster, from the images in
// `useImage`: the cluster's texels (ABRDFs of 3 x images values, linear / alpha) are
// factored by an SVD (eigenvectors of their Gram matrix); texel t's coefficients are
// sqrt(n_c) x its entries of the top `terms` left singular vectors, the first oriented to a
// positive sum (with terms = 1: a brightness factor of mean square 1). Texels x terms.
// channels 3: the same per RGB channel, from the channel's values alone (texels x terms x 3,
// term r and channel c at 3 r + c; with terms = 1 a colour factor).
// Parallel over clusters, each computed alone: the same on any thread count. Costs
// sum_c n_c x min(n_c, 3 x images) x 3 x images multiply-adds (clusters above kExactSvdUpTo:
// about 40 x n_c x 3 x images x (terms + 6), subspace iteration) and n_c x 3 x images floats per
// cluster in flight.
std::vector<float> texelCoefficients(const BtfStack& stack, float alpha, const std::vector<std::int32_t>& ids,
                                     int clusters, const std::vector<std::uint8_t>& useImage, int terms, bool progress,
                                     int channels = 1);

// Clusters whose min(n_c, 3 x images) is above this take the top `terms` singular vectors by
// subspace iteration (topLeftSingularVectors) instead of the exact eigen-decomposition of a
// Gram matrix. At 100 x 100 texels and the default k = 500 the largest clusters of the synthetic
// presets are 147 (fabric), 83 (wool), 49 (corduroy), 109 (satin) and 298 (glossy) texels: all
// but glossy's one keep the exact coefficients, bit for bit.
// Above it the full eigen-decomposition (about 10 m^3 flops, all m eigenvectors for the few
// wanted) costs more than the iteration: at 800 x 800 texels (n_c about 1,300) it took 800 s
// of 1,860 with the threshold at 1,024.
constexpr long kExactSvdUpTo = 256;

// Texels whose values, as floats, the modulation stage may hold per thread: 8 x the mean cluster
// size (and one), at most all of them. The coefficient batches and the refit's chunks take
// their size from it; the memory estimate counts it (pipeline/memory_estimate.cpp).
inline std::size_t modulationTexelsPerThread(std::int64_t texels, int clusters) {
  const std::size_t m = static_cast<std::size_t>(texels);
  return std::min(m, 8 * m / static_cast<std::size_t>(clusters > 1 ? clusters : 1) + 1);
}

// The top `terms` left singular vectors u (n x terms, unit columns) and singular values of y
// (n x dims), by block subspace iteration (block terms + 6, Rayleigh-Ritz each iteration,
// single-threaded BLAS products) until every vector turns by less than about 4e-6 rad per
// iteration (at most 200 iterations). Deterministic for a seed. Signs are arbitrary.
void topLeftSingularVectors(const Eigen::Ref<const Eigen::MatrixXf>& y, int terms, std::uint64_t seed, Eigen::MatrixXd& u,
                            Eigen::VectorXd& sigma, int* iterations = nullptr);

// Refit after training: every texel's coefficients that best mix its cluster's trained terms,
// least squares over `images` (linear / alpha): per cluster the R x R Gram matrix of its terms,
// per texel their dot products with its own values, one small solve. `terms` holds, for each of
// `images` in order and each cluster, its 3 x terms values (term r, channel c at 3 r + c):
// images.size() x clusters x 3 terms, image-major so that the pass over the stack, image by
// image, reads one small block per image. Texels x terms; deterministic for any thread count.
// meanWeight w > 0 also fits each texel's mean over the images (per channel), weighted as w x
// images squared errors: w n |mean of the texel's decoded values - mean of its values|^2 joins
// the sum, so the per-texel mean brightness (what a viewer sees as grain) is kept closer.
// channels 3: each channel's coefficients fit to that channel alone (texels x terms x 3).
std::vector<float> fitTexelCoefficients(const BtfStack& stack, float alpha, const std::vector<std::int32_t>& ids,
                                        int clusters, const std::vector<int>& images, const std::vector<float>& terms,
                                        int termCount, bool progress, double meanWeight = 0, int channels = 1);

}  // namespace nbtf
