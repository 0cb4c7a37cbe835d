#include "cluster/pca.h"

#include <Eigen/QR>
#include <Eigen/SVD>
#include <climits>
#include <cmath>
#include <string>
#include <sstream>

#include "linalg/blas.h"
#include "util/random.h"
#include "util/error.h"
#include "util/parallel.h"
#include "util/progress.h"

namespace nbtf {

double PcaResult::explainedRatio() const {
  return totalVariance > 0 ? explainedVariance.cast<double>().sum() / totalVariance : 0.0;
}

namespace {

int checkedInt(Eigen::Index v) {
  if (v > INT_MAX) throw Error("PCA: a matrix size exceeds the BLAS index range");
  return static_cast<int>(v);
}

// Column means and the total (population) variance; one pass over X, column slice by slice
// (or none, when the source knows them).
void columnStatistics(const AbrdfSource& x, Eigen::VectorXf& mean, double& totalVariance, const std::string& label) {
  if (const ColumnMoments* known = x.knownMoments()) {
    mean = known->mean;
    totalVariance = known->variance.sum();
    return;
  }
  mean.resize(x.cols());
  Eigen::VectorXd variance(x.cols());
  const Eigen::Index rows = x.rows();
  x.forEachColumnSlice([&](Eigen::Index c0, Eigen::Index c1, const float* data) {
    for (Eigen::Index d = c0; d < c1; ++d) {
      double m;
      columnMoments(data + (d - c0) * rows, rows, m, variance[d]);
      if (!std::isfinite(m) || !std::isfinite(variance[d])) {
        std::ostringstream s;
        s << "PCA: dimension " << d << " holds NaN or Inf values";
        throw Error(s.str());
      }
      mean[d] = static_cast<float>(m);
    }
  }, label);
  totalVariance = variance.sum();
}

// Orthonormal basis of the columns (thin Householder QR).
MatrixXfCol orthonormalize(const MatrixXfCol& y) {
  Eigen::HouseholderQR<MatrixXfCol> qr(y);
  return qr.householderQ() * MatrixXfCol::Identity(y.rows(), y.cols());
}

// The centred products, without ever forming X - mean:
//   (X - 1 mean^T) B   = X B   - 1 (mean^T B)
//   (X - 1 mean^T)^T Q = X^T Q - mean (1^T Q)
// X B row slice by row slice, X^T Q column slice by column slice: one single-threaded BLAS
// product per slice (the slices of linalg/blas.cpp's blasMultiply), so every entry is computed
// the same way whatever the thread count and wherever the slice comes from.
MatrixXfCol centredTimes(const AbrdfSource& x, const Eigen::VectorXf& mean, const MatrixXfCol& b,
                         const std::string& label) {
  MatrixXfCol y(x.rows(), b.cols());
  const int n = checkedInt(b.cols()), k = checkedInt(x.cols()), ldc = checkedInt(x.rows());
  x.forEachRowSlice([&](Eigen::Index r0, Eigen::Index r1, const float* data, Eigen::Index ld) {
    gemmOnThisThread(false, false, static_cast<int>(r1 - r0), n, k, data, checkedInt(ld), b.data(), k, y.data() + r0, ldc);
  }, label);
  Eigen::RowVectorXf shift = mean.transpose() * b;
  y.rowwise() -= shift;
  return y;
}
MatrixXfCol centredTransposeTimes(const AbrdfSource& x, const Eigen::VectorXf& mean, const MatrixXfCol& q,
                                  const std::string& label) {
  MatrixXfCol z(x.cols(), q.cols());
  const int n = checkedInt(q.cols()), k = checkedInt(x.rows()), ldc = checkedInt(x.cols());
  x.forEachColumnSlice([&](Eigen::Index c0, Eigen::Index c1, const float* data) {
    gemmOnThisThread(true, false, static_cast<int>(c1 - c0), n, k, data, k, q.data(), k, z.data() + c0, ldc);
  }, label);
  Eigen::RowVectorXf sums = q.colwise().sum();
  z.noalias() -= mean * sums;
  return z;
}

}  // namespace

PcaResult randomizedPca(const MatrixXfCol& x, const PcaOptions& options) {
  return randomizedPca(DenseAbrdfSource(x), options);
}

PcaResult randomizedPca(const AbrdfSource& x, const PcaOptions& options) {
  const Eigen::Index rows = x.rows(), dims = x.cols();
  const Eigen::Index rank = std::min(rows, dims);
  if (options.components < 1 || options.components > rank) {
    std::ostringstream s;
    s << "PCA: " << options.components << " components requested, but " << rows << " texels x " << dims
      << " dimensions allow between 1 and " << rank;
    throw Error(s.str());
  }
  if (options.oversampling < 0) throw Error("PCA: oversampling must be >= 0");
  if (options.powerIterations < 0) throw Error("PCA: power iterations must be >= 0");
  const int components = options.components;
  const Eigen::Index sketch = std::min<Eigen::Index>(components + options.oversampling, rank);

  PcaResult result;
  // One read of X for the statistics (unless the source knows them), 2 q + 2 for the
  // products; a progress bar for each.
  const int passes = 2 * options.powerIterations + 2 + (x.knownMoments() ? 0 : 1);
  int pass = 0;
  auto label = [&](const char* what) {
    ++pass;
    return options.progress ? "pca pass " + std::to_string(pass) + "/" + std::to_string(passes) + " (" + what + ")"
                            : std::string();
  };
  columnStatistics(x, result.mean, result.totalVariance, x.knownMoments() ? "" : label("statistics, dimensions"));

  // Range finder: a Gaussian sketch of the column space, sharpened by power iterations
  // (each one squares the decay of the singular values the sketch must separate).
  StageRandom random(options.seed);
  MatrixXfCol omega(dims, sketch);
  for (Eigen::Index j = 0; j < sketch; ++j)
    for (Eigen::Index d = 0; d < dims; ++d) omega(d, j) = static_cast<float>(random.normal());
  MatrixXfCol q = orthonormalize(centredTimes(x, result.mean, omega, label("sketch, texels")));
  omega.resize(0, 0);
  for (int i = 0; i < options.powerIterations; ++i) {
    MatrixXfCol z = orthonormalize(centredTransposeTimes(x, result.mean, q, label("power iteration, dimensions")));
    q = orthonormalize(centredTimes(x, result.mean, z, label("power iteration, texels")));
  }

  // B = Q^T (X - mean) is small (sketch x D). With B^T = Qb R: B = R^T Qb^T, and the SVD
  // of the tiny R^T = U S W^T gives B = U S (Qb W)^T.
  MatrixXfCol bt = centredTransposeTimes(x, result.mean, q, label("projection, dimensions"));
  Eigen::HouseholderQR<MatrixXfCol> qr(bt);
  MatrixXfCol qb = qr.householderQ() * MatrixXfCol::Identity(dims, sketch);
  Eigen::MatrixXd rt = qr.matrixQR().topRows(sketch).triangularView<Eigen::Upper>().toDenseMatrix().transpose().cast<double>();
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(rt, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::MatrixXf u = svd.matrixU().leftCols(components).cast<float>();
  Eigen::MatrixXf w = svd.matrixV().leftCols(components).cast<float>();
  Eigen::VectorXf sigma = svd.singularValues().head(components).cast<float>();

  result.basis = qb * w;
  result.scores = q * u;
  result.scores *= sigma.asDiagonal();
  result.explainedVariance = sigma.array().square() / static_cast<float>(rows);

  // Signs are arbitrary in an SVD; fix them (largest basis entry positive) so results
  // do not flip between BLAS builds.
  for (int j = 0; j < components; ++j) {
    Eigen::Index at;
    result.basis.col(j).cwiseAbs().maxCoeff(&at);
    if (result.basis(at, j) < 0) {
      result.basis.col(j) *= -1.0f;
      result.scores.col(j) *= -1.0f;
    }
  }
  return result;
}

}  // namespace nbtf
