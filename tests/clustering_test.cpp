#include "cluster/clustering.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "cluster_test_util.h"
#include "util/error.h"
#include "util/parallel.h"

namespace nbtf {
namespace {

using testing::adjustedRandIndex;
using testing::makeBlobs;

TEST(ClusterRepresentatives, MedianIsTakenPerDimension) {
  // Cluster 0: rows 0, 2, 4 (odd count); cluster 1: rows 1, 3, 5, 6 (even count).
  MatrixXfCol x(7, 2);
  x << 1, 9,   //
      10, 0,   //
      5, 3,    //
      40, 7,   //
      3, 2,    //
      20, 5,   //
      30, 1;
  std::vector<std::int32_t> ids = {0, 1, 0, 1, 0, 1, 1};
  MatrixXfCol median = clusterRepresentatives(x, ids, 2, Representative::Median);
  // Per dimension, so the result need not be any member: dim 0 of {1, 5, 3} -> 3 (row 4),
  // dim 1 of {9, 3, 2} -> 3 (row 2).
  EXPECT_FLOAT_EQ(median(0, 0), 3);
  EXPECT_FLOAT_EQ(median(0, 1), 3);
  // Even count: mean of the two middle values. dim 0 of {10, 40, 20, 30} -> 25; dim 1 of {0, 7, 5, 1} -> 3.
  EXPECT_FLOAT_EQ(median(1, 0), 25);
  EXPECT_FLOAT_EQ(median(1, 1), 3);

  MatrixXfCol mean = clusterRepresentatives(x, ids, 2, Representative::Mean);
  EXPECT_FLOAT_EQ(mean(0, 0), 3);
  EXPECT_FLOAT_EQ(mean(0, 1), 14.0f / 3);
  EXPECT_FLOAT_EQ(mean(1, 0), 25);
  EXPECT_FLOAT_EQ(mean(1, 1), 13.0f / 4);
}

TEST(ClusterRepresentatives, MedianMatchesSortingForLargeClustersWithDuplicates) {
  // Clusters of hundreds of texels, values with many ties (8-bit sources repeat values).
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> level(0, 40), cluster(0, 6);
  MatrixXfCol x(3001, 4);
  for (int d = 0; d < 4; ++d)
    for (int t = 0; t < x.rows(); ++t) x(t, d) = d == 0 ? 0.0f : level(rng) * 0.25f - (d == 3 ? rng() % 1000 : 0);
  std::vector<std::int32_t> ids(x.rows());
  for (auto& id : ids) id = cluster(rng);
  MatrixXfCol median = clusterRepresentatives(x, ids, 7, Representative::Median);
  for (int c = 0; c < 7; ++c)
    for (int d = 0; d < 4; ++d) {
      std::vector<float> values;
      for (int t = 0; t < x.rows(); ++t)
        if (ids[t] == c) values.push_back(x(t, d));
      std::sort(values.begin(), values.end());
      std::size_t n = values.size();
      float expected = n % 2 ? values[n / 2] : 0.5f * (values[n / 2 - 1] + values[n / 2]);
      EXPECT_EQ(median(c, d), expected) << "cluster " << c << " dim " << d << " (" << n << " texels)";
    }
}

TEST(ClusterRepresentatives, MedianIgnoresOutliersTheMeanFollows) {
  MatrixXfCol x(5, 1);
  x << 1, 2, 3, 4, 1000;
  std::vector<std::int32_t> ids(5, 0);
  EXPECT_FLOAT_EQ(clusterRepresentatives(x, ids, 1, Representative::Median)(0, 0), 3);
  EXPECT_FLOAT_EQ(clusterRepresentatives(x, ids, 1, Representative::Mean)(0, 0), 202);
}

TEST(ClusterRepresentatives, EmptyClusterGetsTheStandardizedMean) {
  MatrixXfCol x = MatrixXfCol::Constant(4, 3, 2.0f);
  MatrixXfCol r = clusterRepresentatives(x, {0, 0, 2, 2}, 3, Representative::Median);
  EXPECT_TRUE(r.allFinite());
  EXPECT_EQ(r.row(1).norm(), 0.0f);
  EXPECT_FLOAT_EQ(r(2, 1), 2.0f);
}

TEST(ClusterRepresentatives, RejectsInconsistentIds) {
  MatrixXfCol x = MatrixXfCol::Zero(3, 2);
  EXPECT_THROW(clusterRepresentatives(x, {0, 1}, 2, Representative::Median), Error);
  EXPECT_THROW(clusterRepresentatives(x, {0, 1, 2}, 2, Representative::Median), Error);
  EXPECT_THROW(clusterRepresentatives(x, {0, -1, 1}, 2, Representative::Median), Error);
  EXPECT_THROW(clusterRepresentatives(x, {0, 0, 0}, 0, Representative::Median), Error);
}

ClusteringOptions quiet(int clusters, int components) {
  ClusteringOptions o;
  o.clusters = clusters;
  o.pca.components = components;
  o.progress = false;
  return o;
}

TEST(ClusterAbrdfs, ClustersHighDimensionalGroupsThroughPca) {
  // 5 groups of ABRDF-like vectors in 90 dimensions; PCA to 4 components keeps them apart.
  auto blobs = makeBlobs(5, 40, 90, 6.0f, 11);
  ClusteringResult r = clusterAbrdfs(blobs.points, quiet(5, 4));
  EXPECT_DOUBLE_EQ(adjustedRandIndex(r.ids, blobs.truth), 1.0);
  ASSERT_EQ(r.representatives.rows(), 5);
  ASSERT_EQ(r.representatives.cols(), 90);
  EXPECT_EQ(r.explainedVariance.size(), 4);
  EXPECT_GT(r.explainedVarianceRatio, 0.5);
  EXPECT_LE(r.explainedVarianceRatio, 1.0 + 1e-6);
  for (int s : r.sizes) EXPECT_EQ(s, 40);
  // Representatives live in the input space: each is the median of its members, close
  // to the members' mean for Gaussian groups.
  for (int c = 0; c < 5; ++c) {
    Eigen::RowVectorXf mean = Eigen::RowVectorXf::Zero(90);
    for (int i = 0; i < 200; ++i)
      if (r.ids[i] == c) mean += blobs.points.row(i) / 40.0f;
    EXPECT_LT((r.representatives.row(c) - mean).norm() / std::sqrt(90.0f), 0.5f);
  }
  EXPECT_GE(r.pcaSeconds, 0);
  EXPECT_GE(r.kmeansSeconds, 0);
}

TEST(ClusterAbrdfs, SameSeedSameIds) {
  auto blobs = makeBlobs(20, 15, 40, 3.0f, 12);
  ClusteringOptions o = quiet(12, 6);
  o.seed = 5;
  ClusteringResult a = clusterAbrdfs(blobs.points, o), b = clusterAbrdfs(blobs.points, o);
  EXPECT_EQ(a.ids, b.ids);
  EXPECT_EQ(a.representatives, b.representatives);
}

TEST(ClusterAbrdfs, RejectsImpossibleRequests) {
  auto blobs = makeBlobs(2, 10, 6, 5.0f, 13);
  EXPECT_THROW(clusterAbrdfs(blobs.points, quiet(0, 2)), Error);
  try {
    clusterAbrdfs(blobs.points, quiet(21, 2));
    FAIL() << "more clusters than texels accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("only 20 texels"), std::string::npos) << e.what();
  }
  try {
    clusterAbrdfs(blobs.points, quiet(2, 7));
    FAIL() << "more components than dimensions accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("between 1 and 6"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace nbtf
