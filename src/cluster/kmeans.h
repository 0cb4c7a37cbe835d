// k-means++ seeding (D(x)^2 sampling, section 3.2) and Lloyd iterations, multi-threaded
// and deterministic for a seed.
#pragma once
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "preprocess/abrdf_matrix.h"

namespace nbtf {

struct KMeansOptions {
  int clusters = 500;
  int maxIterations = 100;
  std::uint64_t seed = 1;
  bool progress = true;
};

struct KMeansResult {
  std::vector<std::int32_t> ids;  // M: texel -> cluster
  MatrixXfCol centers;            // k x C
  std::vector<int> sizes;         // k
  double inertia = 0;             // sum of squared distances to the assigned centre
  int iterations = 0;
  int reseeded = 0;               // empty clusters re-seeded
};

// points: M x C (one row per texel). Throws nbtf::Error if k < 1 or k > M.
KMeansResult kmeansPlusPlus(const MatrixXfCol& points, const KMeansOptions& options);

}  // namespace nbtf
