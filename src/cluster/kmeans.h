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
  int maxIterations = 300;  // Lloyd rounds; stops earlier when no point changes cluster
  // Also stops once a round moves at most this fraction of the points (and re-seeds none):
  // on large materials a few points on cluster borders can swap back and forth for hundreds
  // of rounds that no longer change the inertia. Below 1 / fraction points (100,000 at the
  // default) that is 0 points: only a round that moves none stops it.
  double settledFraction = 1e-5;
  std::uint64_t seed = 1;
  bool progress = true;
  // Candidates drawn per k-means++ step, the one lowering the potential most is kept
  // ("greedy" k-means++, as scikit-learn does). 0 = 2 + ln k; 1 = the classic algorithm.
  int seedingTrials = 0;
};

struct KMeansResult {
  std::vector<std::int32_t> ids;  // M: texel -> cluster
  MatrixXfCol centers;            // k x C
  std::vector<int> sizes;         // k
  double inertia = 0;             // sum of squared distances to the assigned centre
  int iterations = 0;
  int reseeded = 0;               // empty clusters re-seeded
  bool converged = false;         // stopped because no point (or at most settledFraction of them) changed cluster
  std::size_t lastMoved = 0;      // points the last round moved (0 when fully converged)
  int emptyClusters = 0;          // clusters left empty (only when fewer distinct points than k)
  double seedingSeconds = 0, lloydSeconds = 0;
};

// points: M x C (one row per texel). Throws nbtf::Error if k < 1 or k > M.
KMeansResult kmeansPlusPlus(const MatrixXfCol& points, const KMeansOptions& options);

// Lloyd iterations from given centres (k x C; k = centers.rows(), options.clusters is
// ignored). Same errors as above.
KMeansResult kmeansFromCenters(const MatrixXfCol& points, const MatrixXfCol& centers, const KMeansOptions& options);

// The number of k-means++ candidates per step for k clusters (requested > 0 wins).
int seedingTrialsFor(int k, int requested);

}  // namespace nbtf
