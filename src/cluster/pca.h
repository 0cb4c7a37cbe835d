// PCA by randomized SVD (range finder + power iterations): cost O(M * D * (C + p)),
// never a dense D x D matrix.
#pragma once
#include <Eigen/Core>
#include <cstdint>

#include "preprocess/abrdf_matrix.h"

namespace nbtf {

struct PcaOptions {
  int components = 32;
  int oversampling = 10;
  int powerIterations = 4;
  std::uint64_t seed = 1;
  bool progress = true;
};

struct PcaResult {
  Eigen::VectorXf mean;          // D: column means subtracted before the SVD
  MatrixXfCol basis;             // D x C, orthonormal columns
  MatrixXfCol scores;            // M x C: (X - mean) * basis (computed as the SVD's U * S, which
                                 // equals it up to the part of X the sketch did not capture)
  Eigen::VectorXf explainedVariance;  // C: variance along each component
  double totalVariance = 0;      // sum of the variances of all D dimensions
  double explainedRatio() const; // sum(explainedVariance) / totalVariance
};

// Throws nbtf::Error if components < 1 or components > min(M, D).
PcaResult randomizedPca(const MatrixXfCol& x, const PcaOptions& options);

}  // namespace nbtf
