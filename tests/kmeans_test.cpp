#include "cluster/kmeans.h"

#include <gtest/gtest.h>

#include <limits>

#include "cluster_test_util.h"
#include "util/error.h"
#include "util/parallel.h"

namespace nbtf {
namespace {

using testing::adjustedRandIndex;
using testing::makeBlobs;
using testing::quiet;

// Plain Lloyd in double precision, the reference the accelerated version must reproduce.
std::vector<std::int32_t> referenceLloyd(const MatrixXfCol& points, Eigen::MatrixXd centers, int& iterations) {
  const Eigen::Index m = points.rows(), k = centers.rows();
  Eigen::MatrixXd p = points.cast<double>();
  std::vector<std::int32_t> assign(m, -1);
  for (iterations = 0; iterations < 1000; ++iterations) {
    bool changed = false;
    for (Eigen::Index i = 0; i < m; ++i) {
      Eigen::Index best;
      (centers.rowwise() - p.row(i)).rowwise().squaredNorm().minCoeff(&best);
      if (assign[i] != best) changed = true, assign[i] = static_cast<std::int32_t>(best);
    }
    if (!changed) break;
    Eigen::MatrixXd sums = Eigen::MatrixXd::Zero(k, p.cols());
    Eigen::VectorXd counts = Eigen::VectorXd::Zero(k);
    for (Eigen::Index i = 0; i < m; ++i) sums.row(assign[i]) += p.row(i), counts[assign[i]] += 1;
    for (Eigen::Index j = 0; j < k; ++j)
      if (counts[j] > 0) centers.row(j) = sums.row(j) / counts[j];
  }
  return assign;
}

TEST(KMeans, FindsWellSeparatedBlobs) {
  auto blobs = makeBlobs(8, 60, 5, 40.0f, 1);
  KMeansResult r = kmeansPlusPlus(blobs.points, quiet(8));
  EXPECT_DOUBLE_EQ(adjustedRandIndex(r.ids, blobs.truth), 1.0);
  EXPECT_TRUE(r.converged);
  for (int s : r.sizes) EXPECT_EQ(s, 60);
  // Inertia of the true partition: about M * dims (unit noise per dimension).
  EXPECT_NEAR(r.inertia / (480.0 * 5), 1.0, 0.15);
}

TEST(KMeans, SameSeedSameIdsOnAnyThreadCount) {
  // Overlapping blobs (many iterations), enough points for the seeding to use threads.
  auto blobs = makeBlobs(30, 150, 6, 8.0f, 3);
  setThreadCount(1);
  KMeansResult a = kmeansPlusPlus(blobs.points, quiet(25, 7));
  setThreadCount(2);
  KMeansResult b = kmeansPlusPlus(blobs.points, quiet(25, 7));
  setThreadCount(0);
  EXPECT_EQ(a.ids, b.ids);
  EXPECT_EQ(a.inertia, b.inertia);
  EXPECT_EQ(a.iterations, b.iterations);
  KMeansResult c = kmeansPlusPlus(blobs.points, quiet(25, 8));
  EXPECT_NE(a.ids, c.ids);  // the seed matters
}

TEST(KMeans, BoundsReproducePlainLloyd) {
  // From the same centres, Hamerly's bounds must only skip work, never change the answer.
  auto blobs = makeBlobs(12, 50, 8, 5.0f, 4);
  MatrixXfCol start(20, 8);
  for (int j = 0; j < 20; ++j) start.row(j) = blobs.points.row(j * 29);
  int referenceIterations = 0;
  auto expected = referenceLloyd(blobs.points, start.cast<double>(), referenceIterations);
  KMeansResult r = kmeansFromCenters(blobs.points, start, quiet(20));
  EXPECT_EQ(r.ids, expected);
  EXPECT_TRUE(r.converged);
  EXPECT_EQ(r.iterations, referenceIterations);
}

// What the settling rules are checked on: 600 points in 12 blobs, 20 starting centres, and
// the full run from them (no settling rule).
struct SettlingCase {
  testing::Blobs blobs = makeBlobs(12, 50, 8, 5.0f, 4);
  MatrixXfCol start = MatrixXfCol(20, 8);
  KMeansResult exact;
  SettlingCase() {
    for (int j = 0; j < 20; ++j) start.row(j) = blobs.points.row(j * 29);
    KMeansOptions full = quiet(20);
    full.settledFraction = 0;
    exact = kmeansFromCenters(blobs.points, start, full);
  }
};

// A settled fraction stops Lloyd once a round moves at most that share of the points: no
// later than the full run, with an inertia within a hair of it; below 1 / fraction points it
// is the full run (the default changes nothing under 100,000 points).
TEST(KMeans, ASettledFractionStopsOnceFewPointsMove) {
  const SettlingCase c;
  const auto& [blobs, start, exact] = c;
  ASSERT_TRUE(exact.converged);
  ASSERT_GT(exact.iterations, 3);
  EXPECT_EQ(exact.lastMoved, 0u);
  EXPECT_EQ(kmeansFromCenters(blobs.points, start, quiet(20)).ids, exact.ids);  // default: 600 x 1e-5 = 0 points
  KMeansOptions loose = quiet(20);
  loose.settledFraction = 0.02;  // up to 12 points
  const KMeansResult early = kmeansFromCenters(blobs.points, start, loose);
  EXPECT_TRUE(early.converged);
  EXPECT_LT(early.iterations, exact.iterations);
  EXPECT_LE(early.lastMoved, 12u);
  EXPECT_GT(early.lastMoved, 0u);
  EXPECT_LT(early.inertia, exact.inertia * 1.01);
  KMeansOptions bad = quiet(20);
  bad.settledFraction = 1;
  EXPECT_THROW(kmeansFromCenters(blobs.points, start, bad), Error);
}

// The centre-shift rule stops Lloyd once the centres' squared moves in a round sum to at most
// shiftTolerance x the points' mean variance, with points still moving; it is off (the run is
// the full one) where the settled fraction is under one point, and at 0.
TEST(KMeans, ACentreShiftToleranceStopsOnceTheCentresHardlyMove) {
  const SettlingCase c;
  const auto& [blobs, start, exact] = c;
  ASSERT_TRUE(exact.converged);
  ASSERT_GT(exact.iterations, 3);

  KMeansOptions small = quiet(20);  // 600 x 1e-5 < 1 point: no settling rule
  small.shiftTolerance = 1e3;
  EXPECT_EQ(kmeansFromCenters(blobs.points, start, small).ids, exact.ids);

  KMeansOptions large = quiet(20);
  large.settledFraction = 1.0 / 600 + 1e-9;  // one point: the rules apply
  large.shiftTolerance = 0;
  const KMeansResult off = kmeansFromCenters(blobs.points, start, large);
  large.shiftTolerance = 0.05;
  const KMeansResult early = kmeansFromCenters(blobs.points, start, large);
  EXPECT_TRUE(early.converged);
  EXPECT_LT(early.iterations, off.iterations);
  EXPECT_GT(early.lastMoved, 1u);  // stopped by the shift, not by the moved points
  EXPECT_LT(early.inertia, exact.inertia * 1.05);
  EXPECT_GE(early.inertia, exact.inertia * (1 - 1e-6));

  large.shiftTolerance = -1;
  EXPECT_THROW(kmeansFromCenters(blobs.points, start, large), Error);
  large.shiftTolerance = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(kmeansFromCenters(blobs.points, start, large), Error);
}

TEST(KMeans, InertiaAndCentresMatchTheAssignment) {
  auto blobs = makeBlobs(10, 30, 3, 6.0f, 5);
  KMeansResult r = kmeansPlusPlus(blobs.points, quiet(10));
  ASSERT_TRUE(r.converged);
  double inertia = 0;
  for (Eigen::Index i = 0; i < blobs.points.rows(); ++i) {
    Eigen::Index nearest;
    (r.centers.rowwise() - blobs.points.row(i)).rowwise().squaredNorm().minCoeff(&nearest);
    EXPECT_EQ(nearest, r.ids[i]) << "point " << i << " is not in its nearest cluster";
    inertia += (r.centers.row(r.ids[i]) - blobs.points.row(i)).squaredNorm();
  }
  EXPECT_NEAR(r.inertia, inertia, 1e-4 * inertia);
  // Converged centres are the means of their points.
  for (int j = 0; j < 10; ++j) {
    Eigen::RowVectorXd sum = Eigen::RowVectorXd::Zero(3);
    for (Eigen::Index i = 0; i < blobs.points.rows(); ++i)
      if (r.ids[i] == j) sum += blobs.points.row(i).cast<double>();
    EXPECT_LT((sum / r.sizes[j] - r.centers.row(j).cast<double>()).norm(), 1e-4);
  }
}

TEST(KMeans, OneClusterPerPointHasZeroInertia) {
  auto blobs = makeBlobs(3, 5, 2, 10.0f, 6);
  KMeansResult r = kmeansPlusPlus(blobs.points, quiet(15));
  EXPECT_EQ(r.inertia, 0.0);
  for (int s : r.sizes) EXPECT_EQ(s, 1);
}

TEST(KMeans, EmptyClustersAreReseeded) {
  // One starting centre far from every point: it would stay empty under plain Lloyd.
  auto blobs = makeBlobs(4, 25, 2, 10.0f, 7);
  MatrixXfCol start(4, 2);
  start.row(0) = blobs.points.row(0);
  start.row(1) = blobs.points.row(1);
  start.row(2) = blobs.points.row(2);
  start.row(3) << 1e4f, 1e4f;
  KMeansResult r = kmeansFromCenters(blobs.points, start, quiet(4));
  EXPECT_GE(r.reseeded, 1);
  EXPECT_EQ(r.emptyClusters, 0);
  for (int s : r.sizes) EXPECT_GT(s, 0);
}

TEST(KMeans, FewerDistinctPointsThanClustersLeavesClustersEmpty) {
  MatrixXfCol points(30, 2);
  for (int i = 0; i < 30; ++i) points.row(i) << float(i % 3), 0.0f;  // 3 distinct points
  KMeansResult r = kmeansPlusPlus(points, quiet(5));
  EXPECT_EQ(r.inertia, 0.0);
  EXPECT_EQ(r.emptyClusters, 2);
  EXPECT_TRUE(r.converged);
  int total = 0;
  for (int s : r.sizes) total += s;
  EXPECT_EQ(total, 30);
}

TEST(KMeans, RejectsBadClusterCounts) {
  auto blobs = makeBlobs(2, 5, 2, 10.0f, 8);
  EXPECT_THROW(kmeansPlusPlus(blobs.points, quiet(0)), Error);
  EXPECT_THROW(kmeansPlusPlus(blobs.points, quiet(-3)), Error);
  try {
    kmeansPlusPlus(blobs.points, quiet(11));
    FAIL() << "11 clusters of 10 points accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("only 10 texels"), std::string::npos) << e.what();
  }
  MatrixXfCol bad = blobs.points;
  bad(4, 1) = std::numeric_limits<float>::infinity();
  EXPECT_THROW(kmeansPlusPlus(bad, quiet(2)), Error);
}

}  // namespace
}  // namespace nbtf
