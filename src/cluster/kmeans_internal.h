// Pieces shared by k-means++ seeding and the Lloyd iterations. Internal to the cluster stage.
#pragma once
#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace nbtf {

class Progress;

// Points and centres are kept row-major inside k-means: one point's coordinates are
// contiguous, which is what distance loops and row gathers want.
using RowMatrixXf = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Eigen vectorizes the reduction (a plain loop stays scalar under strict IEEE rules); the
// summation order depends only on `dims`, so results are reproducible.
inline float squaredDistance(const float* a, const float* b, Eigen::Index dims) {
  return (Eigen::Map<const Eigen::VectorXf>(a, dims) - Eigen::Map<const Eigen::VectorXf>(b, dims)).squaredNorm();
}

// Points are processed in fixed blocks of this many rows, whatever the thread count, so
// every floating-point sum and every gathered product is the same from run to run.
constexpr Eigen::Index kPointBlock = 512;

struct Seeding {
  RowMatrixXf centers;               // k x C
  std::vector<std::int32_t> nearest;  // M: index of the closest centre
  std::vector<float> distance2;       // M: squared distance to it
};

// k-means++: D(x)^2 sampling, keeping the best of `trials` candidates per step (the
// candidate that lowers the potential most; trials = 1 is the classic algorithm).
// Triangle-inequality pruning skips every group of points whose centre is too far from
// a candidate to lose any point to it.
Seeding kmeansPlusPlusSeeding(const RowMatrixXf& points, int k, int trials, std::uint64_t seed,
                              Progress* progress);

}  // namespace nbtf
