// The cluster stage on a stack on disk (pipeline/cluster_stack.cpp): clusters of the loaded stack, and the images and summary it writes.
#include "pipeline/cluster_stack.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <set>

#include "codec_fixtures.h"
#include "io/btf_loader.h"
#include "io/image_io.h"
#include "model_test_material.h"
#include "test_util.h"

namespace nbtf {
namespace {
namespace fs = std::filesystem;

ClusterStackOptions quietOptions(int clusters) {
  ClusterStackOptions o;
  o.clustering.clusters = clusters;
  o.clustering.pca.components = 4;
  o.clustering.progress = false;
  o.load.progress = false;
  o.progress = false;
  return o;
}

TEST(ClusterStack, ClustersTheLoadedStackAndWritesItsImagesAndSummary) {
  test::TempDir dir;
  const std::string input = testing::writeTestStack(dir / "stack");
  const ClusterStackOptions o = quietOptions(4);
  const ClusterStackRun run = clusterStack(input, dir / "out", o);
  EXPECT_EQ(run.info.width, 8);
  EXPECT_EQ(run.info.height, 8);
  EXPECT_EQ(run.info.images, 81);
  EXPECT_EQ(run.info.input, input);
  EXPECT_GT(run.info.alpha, 0);
  EXPECT_GT(run.memoryLimit, 0u);
  ASSERT_EQ(run.result.ids.size(), 64u);
  EXPECT_EQ(std::set<std::int32_t>(run.result.ids.begin(), run.result.ids.end()).size(), 4u);
  // The material's four classes are its clusters.
  const testing::TestMaterial m = testing::makeTestMaterial();
  for (int t = 0; t < 64; ++t)
    for (int u = 0; u < 64; ++u)
      ASSERT_EQ(run.result.ids[t] == run.result.ids[u], m.ids[t] == m.ids[u]) << t << " " << u;
  // Each texel's linear RGB averaged over every image of the stack as loaded.
  LoadOptions load;
  load.progress = false;
  const BtfStack stack = loadBtfStack(input, load);
  ASSERT_EQ(run.texelColour.rows(), 64);
  ASSERT_EQ(run.texelColour.cols(), 3);
  std::vector<float> rgb(3 * 64);
  Eigen::MatrixXd mean = Eigen::MatrixXd::Zero(64, 3);
  for (int image = 0; image < 81; ++image) {
    stack.imageLinear(image, rgb.data());
    for (int t = 0; t < 64; ++t)
      for (int c = 0; c < 3; ++c) mean(t, c) += rgb[3 * t + c] / 81.0;
  }
  EXPECT_LT((run.texelColour.cast<double>() - mean).cwiseAbs().maxCoeff(), 1e-5);

  const ClusterOutputFiles files = writeClusterOutputs(run, o, dir / "out");
  for (const std::string& image : {files.labels, files.texelColour, files.clusterColour}) {
    const Image8 read = readImage8(image);
    EXPECT_EQ(read.width, 8) << image;
    EXPECT_EQ(read.height, 8) << image;
  }
  EXPECT_TRUE(fs::exists(files.summary));
  EXPECT_EQ(files.summaryJson["appearance_images"]["texel_colour"], "texel_colour.png");
  EXPECT_EQ(files.summaryJson["space"], clusteringSpaceName(o.space));
  EXPECT_EQ(files.summaryJson["kmeans"]["k"], 4);
}

TEST(ClusterStack, CountsBeyondTheInputAreErrors) {
  test::TempDir dir;
  const std::string input = testing::writeTestStack(dir / "stack");
  test::expectErrorContaining([&] { clusterStack(input, dir / "out", quietOptions(65)); },
                              {"--clusters 65: the input has only 64 texels (8 x 8)"});
  ClusterStackOptions o = quietOptions(4);
  o.clustering.pca.components = 65;
  test::expectErrorContaining([&] { clusterStack(input, dir / "out", o); }, {"--components 65: at most 64"});
}

}  // namespace
}  // namespace nbtf
