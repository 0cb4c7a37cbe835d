// The neural compressor's checks of the cluster count (pipeline/neural_compressor.cpp): the default k capped to the input, and k against the texels.
#include "pipeline/neural_compressor.h"

#include <gtest/gtest.h>

#include <string>

#include "compressor_fixtures.h"
#include "pipeline/compressor.h"
#include "test_util.h"
#include "util/error.h"

namespace nbtf {
namespace {

using testing::contains;
using testing::quickOptions;

TEST(Compressor, MoreClustersThanTexelsIsAClearError) {
  testing::TestMaterial m = testing::makeTestMaterial();
  CompressStats stats;
  try {
    compressStack(m.stack, quickOptions(65), stats);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_TRUE(contains(e.what(), "--clusters 65 is larger than the 64 texels")) << e.what();
  }
}

TEST(CompressConfig, DefaultClusterCountIsCappedToTheInput) {
  EXPECT_EQ(defaultClusterCount(1000, 100 * 100), 1000);
  EXPECT_EQ(defaultClusterCount(1000, 256 * 256), 1000);
  EXPECT_EQ(defaultClusterCount(1000, 48 * 48), 230);  // 2304 texels / 10
  EXPECT_EQ(defaultClusterCount(1000, 9999), 999);
  EXPECT_EQ(defaultClusterCount(250, 48 * 48), 230);
  EXPECT_EQ(defaultClusterCount(100, 48 * 48), 100);
  EXPECT_EQ(defaultClusterCount(1000, 7), 1);  // fewer texels than kTexelsPerDefaultCluster: one cluster
  EXPECT_EQ(defaultClusterCount(0, 48 * 48), 0);  // per-texel stays per-texel
}

// Only a default k is capped (and the config's value recorded); a k given explicitly, PCA and
// per-texel are left alone.
TEST(NeuralCompressor, OnlyTheDefaultClusterCountIsCappedAndRecorded) {
  CompressOptions o;
  o.clusters = 1000;
  o.clustersAreDefault = true;
  CompressStats stats;
  detail::resolveDefaultClusters(o, 48 * 48, stats);
  EXPECT_EQ(o.clusters, 230);
  EXPECT_FALSE(o.clustersAreDefault);
  EXPECT_EQ(stats.clustersConfigured, 1000);
  CompressStats again;
  detail::resolveDefaultClusters(o, 48 * 48, again);  // resolved once: no longer a default
  EXPECT_EQ(o.clusters, 230);
  EXPECT_EQ(again.clustersConfigured, 0);

  CompressOptions uncapped;
  uncapped.clusters = 100;
  uncapped.clustersAreDefault = true;
  CompressStats none;
  detail::resolveDefaultClusters(uncapped, 48 * 48, none);
  EXPECT_EQ(uncapped.clusters, 100);
  EXPECT_EQ(none.clustersConfigured, 0);  // not capped: nothing to record

  CompressOptions pca;
  pca.clusters = 1000;
  pca.clustersAreDefault = true;
  pca.pcaBaseline = true;
  detail::resolveDefaultClusters(pca, 48 * 48, none);
  EXPECT_EQ(pca.clusters, 1000);
}

TEST(NeuralCompressor, ClusterCountsAreCheckedAgainstTheTexels) {
  CompressOptions o;
  o.clusters = 64;
  EXPECT_NO_THROW(detail::checkClusterCounts(o, 64, "the crop"));
  o.clusters = 0;  // per-texel
  EXPECT_NO_THROW(detail::checkClusterCounts(o, 64, "the crop"));
  o.clusters = -1;
  test::expectErrorContaining([&] { detail::checkClusterCounts(o, 64, "the crop"); }, {"--clusters must be >= 0"});
  o.clusters = 65;
  test::expectErrorContaining([&] { detail::checkClusterCounts(o, 64, "the crop"); },
                              {"--clusters 65 is larger than the 64 texels of the crop"});
  o.clusters = 8;
  o.adaptive.enabled = true;
  o.adaptive.maxClusters = 100;
  test::expectErrorContaining([&] { detail::checkClusterCounts(o, 64, "m.btf"); },
                              {"--max-clusters 100 is larger than the 64 texels of m.btf"});
  o.adaptive.enabled = false;
  EXPECT_NO_THROW(detail::checkClusterCounts(o, 64, "m.btf"));
}

}  // namespace
}  // namespace nbtf
