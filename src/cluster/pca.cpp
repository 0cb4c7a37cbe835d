#include "cluster/pca.h"

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <climits>
#include <cmath>
#include <functional>
#include <numeric>
#include <string>
#include <sstream>
#include <vector>

#include "linalg/blas.h"
#include "util/random.h"
#include "util/error.h"
#include "util/parallel.h"
#include "util/progress.h"

namespace nbtf {

Eigen::Index PcaOptions::sampleRows(Eigen::Index dims) const {
  const std::size_t fit = sampleBytes / (sizeof(float) * static_cast<std::size_t>(std::max<Eigen::Index>(dims, 1)));
  return static_cast<Eigen::Index>(std::clamp<std::size_t>(fit, 2048, 16384));
}

bool PcaOptions::samples(Eigen::Index rows, Eigen::Index dims) const {
  const Eigen::Index sample = sampleRows(dims);
  return sampleBytes > 0 && rows >= 4 * sample && sample >= 2 * (components + oversampling);
}

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

using PassLabel = std::function<std::string(const char*)>;

// Range finder: an orthonormal basis (rows x sketch) of the column space of X - mean, from a
// Gaussian sketch sharpened by power iterations (each one squares the decay of the singular
// values the sketch must separate).
MatrixXfCol columnRange(const AbrdfSource& x, const Eigen::VectorXf& mean, Eigen::Index sketch,
                        const PcaOptions& options, const PassLabel& label) {
  StageRandom random(options.seed);
  MatrixXfCol omega(x.cols(), sketch);
  for (Eigen::Index j = 0; j < sketch; ++j)
    for (Eigen::Index d = 0; d < x.cols(); ++d) omega(d, j) = static_cast<float>(random.normal());
  MatrixXfCol q = orthonormalize(centredTimes(x, mean, omega, label("sketch, texels")));
  omega.resize(0, 0);
  for (int i = 0; i < options.powerIterations; ++i) {
    MatrixXfCol z = orthonormalize(centredTransposeTimes(x, mean, q, label("power iteration, dimensions")));
    q = orthonormalize(centredTimes(x, mean, z, label("power iteration, texels")));
  }
  return q;
}

// The SVD of X - mean within the range q: B = Q^T (X - mean) is small (sketch x D). With
// B^T = Qb R: B = R^T Qb^T, and the SVD of the tiny R^T = U S W^T gives B = U S (Qb W)^T.
void svdInColumnRange(const AbrdfSource& x, const MatrixXfCol& q, const PassLabel& label, PcaResult& result,
                      int components) {
  const Eigen::Index dims = x.cols(), sketch = q.cols();
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
  result.explainedVariance = sigma.array().square() / static_cast<float>(x.rows());
}

// `count` distinct texels of `rows`, drawn at random, in increasing order.
std::vector<Eigen::Index> drawTexels(Eigen::Index rows, Eigen::Index count, std::uint64_t seed) {
  std::vector<Eigen::Index> texels(static_cast<std::size_t>(rows));
  std::iota(texels.begin(), texels.end(), Eigen::Index(0));
  SplitMix64 random(SplitMix64::mix(seed, 0x73616d706c65ull));  // a stream of its own ("sample")
  for (Eigen::Index i = 0; i < count; ++i)
    std::swap(texels[i], texels[i + static_cast<Eigen::Index>(random.below(static_cast<std::uint64_t>(rows - i)))]);
  texels.resize(static_cast<std::size_t>(count));
  std::sort(texels.begin(), texels.end());
  return texels;
}

// The SVD of X - mean within the row space that a sample of its texels spans: V (D x sketch,
// orthonormal) from the sample, Y = (X - mean) V over every texel, and the eigenvectors W of
// Y^T Y (sketch x sketch; summed in double) give basis V W and scores Y W, exact projections.
void svdInSampledRowRange(const AbrdfSource& x, const PcaOptions& options, Eigen::Index sketch, const PassLabel& label,
                          PcaResult& result) {
  const std::vector<Eigen::Index> texels = drawTexels(x.rows(), options.sampleRows(x.cols()), options.seed);
  MatrixXfCol v;
  {
    const MatrixXfCol sample = x.gatherRows(texels, label("sample, texels"));
    const DenseAbrdfSource sampled(sample);
    const PassLabel inMemory = [](const char*) { return std::string(); };
    const MatrixXfCol q = columnRange(sampled, result.mean, sketch, options, inMemory);
    v = orthonormalize(centredTransposeTimes(sampled, result.mean, q, ""));
  }
  const MatrixXfCol y = centredTimes(x, result.mean, v, label("projection, texels"));
  Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(sketch, sketch);
  constexpr Eigen::Index kBlock = 4096;
  for (Eigen::Index r0 = 0; r0 < y.rows(); r0 += kBlock) {
    const auto block = y.middleRows(r0, std::min(kBlock, y.rows() - r0));
    gram += (block.transpose() * block).cast<double>();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(gram);  // ascending
  const int components = options.components;
  Eigen::MatrixXf w = eigen.eigenvectors().rightCols(components).rowwise().reverse().cast<float>();
  Eigen::VectorXd variance = eigen.eigenvalues().tail(components).reverse().cwiseMax(0.0);
  result.basis = v * w;
  result.scores = y * w;
  result.explainedVariance = (variance / static_cast<double>(x.rows())).cast<float>();
  result.sampledTexels = static_cast<Eigen::Index>(texels.size());
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
  const Eigen::Index sketch = std::min<Eigen::Index>(options.components + options.oversampling, rank);
  const bool sampled = options.samples(rows, dims);

  PcaResult result;
  // One read of X for the statistics (unless the source knows them), then 2 q + 2 for the
  // products, or 2 when sampling; a progress bar for each.
  const int passes = (sampled ? 2 : 2 * options.powerIterations + 2) + (x.knownMoments() ? 0 : 1);
  int pass = 0;
  const PassLabel label = [&](const char* what) {
    ++pass;
    return options.progress ? "pca pass " + std::to_string(pass) + "/" + std::to_string(passes) + " (" + what + ")"
                            : std::string();
  };
  columnStatistics(x, result.mean, result.totalVariance, x.knownMoments() ? "" : label("statistics, dimensions"));
  if (sampled) {
    svdInSampledRowRange(x, options, sketch, label, result);
  } else {
    const MatrixXfCol q = columnRange(x, result.mean, sketch, options, label);
    svdInColumnRange(x, q, label, result, options.components);
  }

  // Signs are arbitrary in an SVD; fix them (largest basis entry positive) so results
  // do not flip between BLAS builds.
  for (int j = 0; j < options.components; ++j) {
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
