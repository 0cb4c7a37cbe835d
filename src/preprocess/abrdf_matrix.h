// ABRDF matrix and the paper's preprocessing (section 2.3 of the clustered neural BTF).
//
// The data matrix X is M x D, column-major, M = texels, D = 3 * images; column
// 3 * image + channel holds one image channel over all texels (so filling it from the
// image-major stack is a contiguous write). Row t is texel t's ABRDF.
#pragma once
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "io/btf_stack.h"
#include "linalg/blas.h"

namespace nbtf {

// Linear ABRDF matrix of the stack (M x 3N). The only float32 copy of the data.
MatrixXfCol abrdfMatrix(const BtfStack& stack, bool progress = true);

// The statistics of x2 = log(x1 + 1) standardized per dimension (eq. 1-4), kept so the
// same transform can be applied to other data later.
struct Standardization {
  Eigen::VectorXf mean;    // D: mean of log(x + 1) over texels
  Eigen::VectorXf stddev;  // D: std of log(x + 1) over texels (population); 0 for constant dims
  // Applies log(x + 1), then (x - mean) / stddev; dimensions with zero variance map to 0.
  void apply(MatrixXfCol& x) const;
  void applyRow(float* row) const;  // one ABRDF (D floats), in place
  // Inverse: standardized -> linear (x = exp(z * stddev + mean) - 1).
  void invert(MatrixXfCol& z) const;
};

// Fits the standardization on X (linear values) and applies it in place (no second copy).
Standardization standardizeInPlace(MatrixXfCol& x);

// The mean and population variance of one column: float sums over runs of 1024 values
// (vectorized, so they depend on the column's address modulo the SIMD width), accumulated in
// double; the squares taken about the mean rounded to float.
void columnMoments(const float* column, Eigen::Index rows, double& mean, double& variance);

// The moments (columnMoments) of every column of the standardized X: what PCA centres by.
struct ColumnMoments {
  Eigen::VectorXf mean;      // D, rounded to float
  Eigen::VectorXd variance;  // D
};

// The same statistics (bit for bit) from the stack, streaming: one image's three columns at a
// time per thread, never the M x 3N matrix. Progress in images. From the same pass (a
// computed stack's pass costs much more than the arithmetic): with `alpha`, targetAlpha's
// value; with `standardized`, the moments of the standardized columns, bit for bit what a
// pass over X would give (each column is laid out where X would hold it).
Standardization fitStandardization(const BtfStack& stack, bool progress = true, float* alpha = nullptr,
                                   ColumnMoments* standardized = nullptr);

// log(x + 1) elementwise, in place: the transform standardization applies (value by value,
// so any layout of the values gives the same results).
void log1pRun(float* values, Eigen::Index n);

// log(x + 1) of the 256 linear values of an 8-bit stack, indexed by the byte (log1pRun's
// bits): what X holds for each byte before it is standardized.
std::vector<float> log1pOfSrgb8();

// alpha of eq. (5): the global maximum of the linear values; targets are values / alpha.
// Throws nbtf::Error if the stack is all zero (nothing to normalize by).
float targetAlpha(const BtfStack& stack);

}  // namespace nbtf
