// k-means++ seeding (cluster/kmeans_seeding.cpp): D(x)^2 sampling with the best of several candidates, deterministic for a seed.
#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <vector>

#include "cluster/kmeans.h"
#include "cluster/kmeans_internal.h"
#include "cluster_test_util.h"
#include "util/parallel.h"

namespace nbtf {
namespace {

using testing::adjustedRandIndex;
using testing::makeBlobs;
using testing::quiet;

RowMatrixXf rowMajor(const MatrixXfCol& points) { return points; }

TEST(KMeans, ClassicSeedingAlsoWorks) {
  auto blobs = makeBlobs(6, 40, 4, 40.0f, 2);
  KMeansOptions o = quiet(6);
  o.seedingTrials = 1;
  KMeansResult r = kmeansPlusPlus(blobs.points, o);
  EXPECT_GT(adjustedRandIndex(r.ids, blobs.truth), 0.99);
}

// The centres are input points, and every point's nearest centre and squared distance are exact.
TEST(KMeansSeeding, CentresAreInputPointsAndNearestIsExact) {
  auto blobs = makeBlobs(5, 30, 3, 10.0f, 4);
  const RowMatrixXf points = rowMajor(blobs.points);
  for (int trials : {1, 3}) {
    const Seeding s = kmeansPlusPlusSeeding(points, 7, trials, 11, nullptr);
    ASSERT_EQ(s.centers.rows(), 7);
    ASSERT_EQ(s.nearest.size(), 150u);
    std::set<int> chosen;
    for (int c = 0; c < 7; ++c) {
      int match = -1;
      for (int i = 0; i < 150 && match < 0; ++i)
        if (points.row(i) == s.centers.row(c)) match = i;
      EXPECT_GE(match, 0) << "centre " << c << " is no input point";
      chosen.insert(match);
    }
    EXPECT_EQ(chosen.size(), 7u);  // distinct points
    for (int i = 0; i < 150; ++i) {
      float best = INFINITY;
      for (int c = 0; c < 7; ++c) best = std::min(best, squaredDistance(points.row(i).data(), s.centers.row(c).data(), 3));
      ASSERT_EQ(s.distance2[i], squaredDistance(points.row(i).data(), s.centers.row(s.nearest[i]).data(), 3));
      ASSERT_EQ(s.distance2[i], best) << "point " << i;
    }
  }
}

// Far-apart blobs: D(x)^2 sampling puts one centre in each blob.
TEST(KMeansSeeding, OneCentrePerWellSeparatedBlob) {
  auto blobs = makeBlobs(6, 40, 4, 200.0f, 5);
  const RowMatrixXf points = rowMajor(blobs.points);
  const Seeding s = kmeansPlusPlusSeeding(points, 6, 2, 3, nullptr);
  std::set<int> blobsHit;
  for (int c = 0; c < 6; ++c)
    for (int i = 0; i < points.rows(); ++i)
      if (points.row(i) == s.centers.row(c)) blobsHit.insert(blobs.truth[i]);
  EXPECT_EQ(blobsHit.size(), 6u);
  EXPECT_DOUBLE_EQ(adjustedRandIndex(s.nearest, blobs.truth), 1.0);
}

TEST(KMeansSeeding, SameSeedSameCentresOnAnyThreadCount) {
  auto blobs = makeBlobs(20, 100, 5, 8.0f, 6);  // 2000 points: several point blocks
  const RowMatrixXf points = rowMajor(blobs.points);
  setThreadCount(1);
  const Seeding a = kmeansPlusPlusSeeding(points, 16, 4, 9, nullptr);
  setThreadCount(2);
  const Seeding b = kmeansPlusPlusSeeding(points, 16, 4, 9, nullptr);
  setThreadCount(0);
  EXPECT_EQ(a.centers, b.centers);
  EXPECT_EQ(a.nearest, b.nearest);
  EXPECT_EQ(a.distance2, b.distance2);
  EXPECT_NE(kmeansPlusPlusSeeding(points, 16, 4, 10, nullptr).centers, a.centers);  // the seed matters
}

// More candidates per step never do worse on average: the greedy variant's potential (the sum
// of D(x)^2) is at most the classic one's over a few seeds.
TEST(KMeansSeeding, MoreCandidatesLowerThePotential) {
  auto blobs = makeBlobs(12, 50, 4, 10.0f, 7);
  const RowMatrixXf points = rowMajor(blobs.points);
  double classic = 0, greedy = 0;
  for (std::uint64_t seed = 1; seed <= 8; ++seed) {
    for (float d : kmeansPlusPlusSeeding(points, 12, 1, seed, nullptr).distance2) classic += d;
    for (float d : kmeansPlusPlusSeeding(points, 12, 5, seed, nullptr).distance2) greedy += d;
  }
  EXPECT_LT(greedy, classic);
}

}  // namespace
}  // namespace nbtf
