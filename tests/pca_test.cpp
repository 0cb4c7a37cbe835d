#include "cluster/pca.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <random>

#include "util/error.h"
#include "util/parallel.h"

namespace nbtf {
namespace {

MatrixXfCol gaussian(int rows, int cols, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> n(0.0f, 1.0f);
  MatrixXfCol m(rows, cols);
  for (int c = 0; c < cols; ++c)
    for (int r = 0; r < rows; ++r) m(r, c) = n(rng);
  return m;
}

PcaOptions quietOptions(int components) {
  PcaOptions o;
  o.components = components;
  o.progress = false;
  return o;
}

// A decaying spectrum (column scales 10, 7, 5, 3.5, ... plus isotropic noise), rotated.
MatrixXfCol decayingSpectrum(int rows, int dims) {
  MatrixXfCol z = gaussian(rows, dims, 4);
  Eigen::MatrixXf rotation = Eigen::HouseholderQR<Eigen::MatrixXf>(gaussian(dims, dims, 5)).householderQ();
  for (int d = 0; d < dims; ++d) z.col(d) *= 10.0f * std::pow(0.7f, d) + 0.1f;
  return z * rotation.transpose();
}

TEST(Pca, RecoversTheSubspaceOfExactlyLowRankData) {
  const int rows = 400, dims = 300, rank = 6;
  MatrixXfCol factors = gaussian(rows, rank, 1);
  MatrixXfCol loadings = gaussian(rank, dims, 2);
  Eigen::RowVectorXf offset = gaussian(1, dims, 3).row(0) * 5.0f;  // data not centred
  MatrixXfCol x = factors * loadings;
  x.rowwise() += offset;

  PcaResult pca = randomizedPca(x, quietOptions(rank));
  ASSERT_EQ(pca.basis.rows(), dims);
  ASSERT_EQ(pca.basis.cols(), rank);
  EXPECT_NEAR(pca.explainedRatio(), 1.0, 1e-4);
  // Orthonormal basis.
  EXPECT_LT((pca.basis.transpose() * pca.basis - Eigen::MatrixXf::Identity(rank, rank)).norm(), 1e-4f);
  // Every true loading direction (after centring) lies in the recovered subspace.
  Eigen::MatrixXf centredLoadings = loadings.transpose();  // dims x rank
  Eigen::MatrixXf residual = centredLoadings - pca.basis * (pca.basis.transpose() * centredLoadings);
  EXPECT_LT(residual.norm() / centredLoadings.norm(), 1e-4f);
  // The column means are the offset plus the factors' means; scores are the centred projection.
  Eigen::RowVectorXf mean = x.colwise().mean();
  EXPECT_LT((pca.mean.transpose() - mean).norm(), 1e-3f);
  MatrixXfCol projected = (x.rowwise() - mean) * pca.basis;
  EXPECT_LT((projected - pca.scores).norm() / projected.norm(), 1e-4f);
}

TEST(Pca, MatchesTheExactEigendecomposition) {
  const int rows = 800, dims = 300, components = 5;  // the sketch (53 columns) sees part of it
  MatrixXfCol x = decayingSpectrum(rows, dims);

  PcaResult pca = randomizedPca(x, quietOptions(components));
  Eigen::MatrixXd xd = x.cast<double>();
  Eigen::MatrixXd centred = xd.rowwise() - xd.colwise().mean();
  Eigen::MatrixXd covariance = centred.transpose() * centred / rows;  // population, as nbtf reports
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(covariance);
  for (int c = 0; c < components; ++c) {
    double exact = eig.eigenvalues()[dims - 1 - c];
    EXPECT_NEAR(pca.explainedVariance[c], exact, 1e-3 * exact) << "component " << c;
    double alignment = std::abs(eig.eigenvectors().col(dims - 1 - c).dot(pca.basis.col(c).cast<double>()));
    EXPECT_GT(alignment, 0.999) << "component " << c;
  }
  EXPECT_NEAR(pca.totalVariance, covariance.trace(), 1e-4 * covariance.trace());
  // Components come out sorted by variance.
  for (int c = 1; c < components; ++c) EXPECT_GE(pca.explainedVariance[c - 1], pca.explainedVariance[c]);
}

TEST(Pca, LargeMaterialsFindTheSubspaceOnASampleOfTexels) {
  const int rows = 10000, dims = 120, components = 5;
  MatrixXfCol x = decayingSpectrum(rows, dims);
  PcaOptions sampling = quietOptions(components), everyTexel = quietOptions(components);
  sampling.sampleBytes = 1;  // the smallest sample: 2048 texels, and 10,000 >= 4 x 2048
  everyTexel.sampleBytes = 0;
  ASSERT_EQ(sampling.sampleRows(dims), 2048);
  ASSERT_TRUE(sampling.samples(rows, dims));
  ASSERT_FALSE(everyTexel.samples(rows, dims));
  PcaResult sampled = randomizedPca(x, sampling), full = randomizedPca(x, everyTexel);
  EXPECT_EQ(sampled.sampledTexels, 2048);
  EXPECT_EQ(full.sampledTexels, 0);

  Eigen::MatrixXd xd = x.cast<double>();
  Eigen::MatrixXd centred = xd.rowwise() - xd.colwise().mean();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(centred.transpose() * centred / rows);
  for (const PcaResult* pca : {&sampled, &full}) {
    for (int c = 0; c < components; ++c) {
      const double exact = eig.eigenvalues()[dims - 1 - c];
      EXPECT_NEAR(pca->explainedVariance[c], exact, 1e-3 * exact) << "component " << c;
      const double alignment = std::abs(eig.eigenvectors().col(dims - 1 - c).dot(pca->basis.col(c).cast<double>()));
      EXPECT_GT(alignment, 0.999) << "component " << c;
    }
    EXPECT_LT((pca->basis.transpose() * pca->basis - Eigen::MatrixXf::Identity(components, components)).norm(), 1e-4f);
  }
  // Every texel is projected onto the sampled subspace: the scores are (X - mean) * basis.
  MatrixXfCol projected = (x.rowwise() - x.colwise().mean()) * sampled.basis;
  EXPECT_LT((projected - sampled.scores).norm() / projected.norm(), 1e-5f);
  EXPECT_EQ(sampled.totalVariance, full.totalVariance);
}

TEST(Pca, TheSampleFollowsTheSeedNotTheThreadCount) {
  MatrixXfCol x = decayingSpectrum(9000, 64);
  PcaOptions o = quietOptions(4);
  o.sampleBytes = 1;
  setThreadCount(1);
  PcaResult a = randomizedPca(x, o);
  setThreadCount(2);
  PcaResult b = randomizedPca(x, o);
  setThreadCount(0);
  EXPECT_EQ(a.basis, b.basis);
  EXPECT_EQ(a.scores, b.scores);
  o.seed = 2;
  PcaResult c = randomizedPca(x, o);
  EXPECT_NE(a.basis, c.basis);
  EXPECT_GT(std::abs(a.basis.col(0).dot(c.basis.col(0))), 0.999f);  // another sample, the same leading direction
}

TEST(Pca, TheSampleFitsItsMemoryAndOnlyLargeMaterialsTakeOne) {
  const PcaOptions o;  // 256 MiB of floats
  EXPECT_EQ(o.sampleRows(3 * 6561), 3409);     // a UBO2003 material: 268,435,456 / (4 x 19,683)
  EXPECT_EQ(o.sampleRows(3 * 22801), 2048);    // a UBO2014 one: 981 texels fit, raised to the floor
  EXPECT_EQ(o.sampleRows(3 * 81), 16384);      // one view: capped
  EXPECT_FALSE(o.samples(100 * 100, 3 * 6561));
  EXPECT_FALSE(o.samples(4 * 3409 - 1, 3 * 6561));
  EXPECT_TRUE(o.samples(4 * 3409, 3 * 6561));
  EXPECT_TRUE(o.samples(256 * 256, 3 * 6561));
  EXPECT_TRUE(o.samples(256 * 256, 3 * 81));   // 4 x 16,384
  EXPECT_FALSE(o.samples(256 * 256 - 1, 3 * 81));
  // A sketch the sample could not hold twice over: every texel instead.
  PcaOptions wide;
  wide.components = 1700;  // sketch 1748; 2 x 1748 > 3409
  EXPECT_FALSE(wide.samples(256 * 256, 3 * 6561));
  wide.components = 1650;  // 2 x 1698 <= 3409
  EXPECT_TRUE(wide.samples(256 * 256, 3 * 6561));
}

TEST(Pca, SameSeedSameResult) {
  MatrixXfCol x = gaussian(200, 50, 6);
  PcaResult a = randomizedPca(x, quietOptions(4)), b = randomizedPca(x, quietOptions(4));
  EXPECT_EQ(a.basis, b.basis);
  EXPECT_EQ(a.scores, b.scores);
}

TEST(Pca, SameResultOnAnyThreadCount) {
  // Large enough for the products to be split into several slices.
  MatrixXfCol x = gaussian(2100, 700, 10);
  setThreadCount(1);
  PcaResult a = randomizedPca(x, quietOptions(8));
  setThreadCount(2);
  PcaResult b = randomizedPca(x, quietOptions(8));
  setThreadCount(0);
  EXPECT_EQ(a.basis, b.basis);
  EXPECT_EQ(a.scores, b.scores);
}

TEST(Pca, AllComponentsOfASmallMatrixAreExact) {
  // components = min(M, D): the sketch spans everything, the explained ratio is 1.
  MatrixXfCol x = gaussian(12, 30, 7);
  PcaResult pca = randomizedPca(x, quietOptions(12));
  EXPECT_NEAR(pca.explainedRatio(), 1.0, 1e-4);
}

TEST(Pca, RejectsImpossibleComponentCounts) {
  MatrixXfCol x = gaussian(10, 50, 8);
  EXPECT_THROW(randomizedPca(x, quietOptions(0)), Error);
  try {
    randomizedPca(x, quietOptions(11));
    FAIL() << "11 components of a 10-row matrix accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("between 1 and 10"), std::string::npos) << e.what();
  }
  MatrixXfCol bad = gaussian(10, 5, 9);
  bad(3, 2) = std::nanf("");
  EXPECT_THROW(randomizedPca(bad, quietOptions(2)), Error);
}

}  // namespace
}  // namespace nbtf
