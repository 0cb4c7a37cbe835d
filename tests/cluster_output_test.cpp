#include "cluster/cluster_output.h"

#include <gtest/gtest.h>

#include <set>

#include "util/error.h"

namespace nbtf {
namespace {

TEST(ClusterOutput, LabelColoursAreDistinctAndReadBack) {
  std::set<std::array<std::uint8_t, 3>> seen;
  for (int id = 0; id < 70000; ++id) {
    auto c = labelColour(id);
    ASSERT_TRUE(seen.insert(c).second) << "id " << id << " shares a colour";
    ASSERT_EQ(labelFromColour(c.data()), id);
  }
  auto c = labelColour((1 << 24) - 1);
  EXPECT_EQ(labelFromColour(c.data()), (1 << 24) - 1);
  // Neighbouring ids do not get neighbouring colours.
  auto a = labelColour(0), b = labelColour(1);
  int difference = std::abs(a[0] - b[0]) + std::abs(a[1] - b[1]) + std::abs(a[2] - b[2]);
  EXPECT_GT(difference, 60);
}

TEST(ClusterOutput, LabelImageIsRowMajorTexels) {
  Image8 image = labelImage({0, 1, 2, 1, 1, 0}, 3, 2);
  EXPECT_EQ(image.width, 3);
  EXPECT_EQ(image.height, 2);
  EXPECT_EQ(labelFromColour(&image.rgb[3 * 2]), 2);  // x = 2, y = 0
  EXPECT_EQ(labelFromColour(&image.rgb[3 * 5]), 0);  // x = 2, y = 1
  EXPECT_THROW(labelImage({0, 1, 2}, 2, 2), Error);
}

TEST(ClusterOutput, MeanColoursPerTexelAndPerCluster) {
  // 3 texels x 2 images: texel t, image i, channel c holds t + i + 0.1 c.
  MatrixXfCol x(3, 6);
  for (int t = 0; t < 3; ++t)
    for (int i = 0; i < 2; ++i)
      for (int c = 0; c < 3; ++c) x(t, 3 * i + c) = t + i + 0.1f * c;
  Eigen::MatrixXf texel = texelMeanColour(x);
  EXPECT_FLOAT_EQ(texel(2, 1), 2.5f + 0.1f);  // (2 + 0 + 0.1 + 2 + 1 + 0.1) / 2
  Eigen::MatrixXf cluster = clusterMeanColour(texel, {0, 1, 0}, 2);
  EXPECT_FLOAT_EQ(cluster(0, 0), 1.5f);  // texels 0 and 2: (0.5 + 2.5) / 2
  EXPECT_FLOAT_EQ(cluster(2, 0), 1.5f);
  EXPECT_FLOAT_EQ(cluster(1, 2), 1.7f);
  Image8 image = colourImage(cluster, 3, 1, 1.7f);
  EXPECT_EQ(image.rgb[3 * 1 + 2], 255);  // the scale maps to white
  EXPECT_THROW(colourImage(cluster, 2, 2, 1.0f), Error);
}

TEST(ClusterOutput, SizeHistogramUsesPowerOfTwoBins) {
  auto bins = sizeHistogram({1, 2, 3, 4, 9, 0, 5});
  ASSERT_EQ(bins.size(), 5u);
  EXPECT_EQ(bins[0].smallest, 0);
  EXPECT_EQ(bins[0].clusters, 1);
  EXPECT_EQ(bins[1].smallest, 1);
  EXPECT_EQ(bins[1].clusters, 1);
  EXPECT_EQ(bins[2].smallest, 2);
  EXPECT_EQ(bins[2].largest, 3);
  EXPECT_EQ(bins[2].clusters, 2);
  EXPECT_EQ(bins[3].clusters, 2);  // 4 and 5
  EXPECT_EQ(bins[4].smallest, 8);
  EXPECT_EQ(bins[4].largest, 9);
  EXPECT_EQ(bins[4].clusters, 1);
}

TEST(ClusterOutput, SummaryReportsTheRun) {
  ClusteringResult r;
  r.ids = {0, 0, 1, 1, 1, 2};
  r.sizes = {2, 3, 1};
  r.representatives = MatrixXfCol::Zero(3, 12);
  r.inertia = 6.0;
  r.iterations = 4;
  r.converged = true;
  r.explainedVariance = Eigen::VectorXf::Constant(2, 1.5f);
  r.explainedVarianceRatio = 0.75;
  ClusteringOptions o;
  o.clusters = 3;
  ClusterRunInfo info;
  info.input = "/data/wool";
  info.width = 3, info.height = 2, info.images = 4;
  auto j = clusteringSummary(r, o, info);
  EXPECT_EQ(j["kmeans"]["k"], 3);
  EXPECT_EQ(j["kmeans"]["last_moved_texels"], 0);
  EXPECT_DOUBLE_EQ(j["kmeans"]["inertia_per_texel"].get<double>(), 1.0);
  EXPECT_DOUBLE_EQ(j["pca"]["explained_variance_ratio"].get<double>(), 0.75);
  EXPECT_EQ(j["cluster_sizes"]["max"], 3);
  EXPECT_EQ(j["clusters"].size(), 3u);
  EXPECT_EQ(j["clusters"][1]["size"], 3);
  EXPECT_TRUE(j["seconds"].contains("pca"));
  EXPECT_EQ(j["input"], "/data/wool");
  // The explained variance says which values it is of.
  EXPECT_EQ(j["pca"]["space"], "standardized log(x + 1) ABRDFs");
  r.lastMoved = 7;  // stopped by a settling rule
  EXPECT_EQ(clusteringSummary(r, o, info)["kmeans"]["last_moved_texels"], 7);
  info.space = ClusteringSpace::Linear;
  EXPECT_EQ(clusteringSummary(r, o, info)["pca"]["space"], "linear ABRDFs / alpha");
}

}  // namespace
}  // namespace nbtf
