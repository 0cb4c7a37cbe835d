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
  // Two settling rules stop a round that re-seeds no cluster early: on large materials points
  // on cluster borders can swap back and forth for hundreds of rounds that no longer change
  // the inertia. Both apply only where settledFraction x points >= 1 (100,000 points at the
  // default); smaller sets run until a round moves no point.
  // 1. The round moved at most this fraction of the points.
  double settledFraction = 1e-5;
  // 2. The centres' squared moves in the round sum to at most this times the points' mean
  //    variance per coordinate (scikit-learn's tol). 0 turns the rule off.
  double shiftTolerance = 1e-4;
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
  bool converged = false;         // stopped because no point changed cluster, or by a settling rule
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
