// `nbtf cluster` end to end: the built binary on a small stack written here.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "cluster/cluster_output.h"
#include "cluster/clustering.h"
#include "io/btf_names.h"
#include "io/image_io.h"
#include "util/atomic_file.h"

namespace nbtf {
namespace {

namespace fs = std::filesystem;

class ClusterCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() / ("nbtf_cluster_cli_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    fs::create_directories(root_);
    writeTwoMaterialStack(root_ / "stack");
  }
  void TearDown() override { fs::remove_all(root_); }

  // 12 x 8 texels, 2 lights x 2 views, UBO2003 layout. Left half: a red diffuse material;
  // right half: a blue one whose brightness follows the light differently. Small per-texel
  // variation so no two ABRDFs are identical.
  static void writeTwoMaterialStack(const fs::path& dir) {
    std::vector<Direction> lights = {{0, 0}, {60, 90}}, views = {{0, 0}, {45, 180}};
    int index = 0;
    for (std::size_t l = 0; l < lights.size(); ++l)
      for (std::size_t v = 0; v < views.size(); ++v, ++index) {
        fs::path folder = dir / viewFolderName(views[v]);
        fs::create_directories(folder);
        std::vector<float> rgb(12 * 8 * 3);
        for (int y = 0; y < 8; ++y)
          for (int x = 0; x < 12; ++x) {
            float jitter = 0.02f * ((x * 7 + y * 3) % 5);
            float* p = &rgb[3 * (y * 12 + x)];
            if (x < 6) {
              float shade = l == 0 ? 0.6f : 0.3f;
              p[0] = shade + jitter, p[1] = 0.1f, p[2] = 0.1f;
            } else {
              float shade = (l == 0 ? 0.2f : 0.5f) + (v == 0 ? 0.1f : 0.0f);
              p[0] = 0.05f, p[1] = 0.1f, p[2] = shade + jitter;
            }
          }
        writeImageSrgb8((folder / ubo2003FileName(index, lights[l], views[v], ".png")).string(), ImageFormat::Png,
                        12, 8, rgb.data());
      }
  }

  int run(const std::string& arguments, std::string& output) {
    fs::path log = root_ / "log.txt";
    std::string command = std::string(NBTF_BIN_DIR) + "/nbtf cluster " + arguments + " > " + log.string() + " 2>&1";
    int status = std::system(command.c_str());
    std::ifstream in(log);
    std::stringstream s;
    s << in.rdbuf();
    output = s.str();
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

  fs::path root_;
};

TEST_F(ClusterCliTest, WritesLabelImageAndSummary) {
  std::string output;
  fs::path out = root_ / "out";
  int code = run((root_ / "stack").string() + " --clusters 2 --components 2 -q -o " + out.string(), output);
  ASSERT_EQ(code, 0) << output;
  EXPECT_NE(output.find("into 2 clusters"), std::string::npos) << output;

  Image8 labels = readImage8((out / "labels.png").string());
  ASSERT_EQ(labels.width, 12);
  ASSERT_EQ(labels.height, 8);
  // Exactly the two materials: every texel of a half has that half's cluster.
  int left = labelFromColour(&labels.rgb[0]), right = labelFromColour(&labels.rgb[3 * 11]);
  EXPECT_NE(left, right);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 12; ++x)
      EXPECT_EQ(labelFromColour(&labels.rgb[3 * (y * 12 + x)]), x < 6 ? left : right) << x << "," << y;

  // Appearance images: the two materials' colours per texel, and per cluster (the jitter
  // inside each half averages out).
  Image8 texelColour = readImage8((out / "texel_colour.png").string());
  Image8 clusterColour = readImage8((out / "cluster_colour.png").string());
  ASSERT_EQ(texelColour.width, 12);
  ASSERT_EQ(clusterColour.height, 8);
  EXPECT_GT(texelColour.rgb[0], texelColour.rgb[2]);        // left: red
  EXPECT_LT(texelColour.rgb[3 * 11], texelColour.rgb[3 * 11 + 2]);  // right: blue
  EXPECT_NE(texelColour.rgb[0], texelColour.rgb[3 * 1]);  // jitter between texels
  EXPECT_EQ(clusterColour.rgb[0], clusterColour.rgb[3 * 1]);  // one colour per cluster

  std::ifstream in(out / "summary.json");
  nlohmann::json summary = nlohmann::json::parse(in);
  EXPECT_EQ(summary["kmeans"]["k"], 2);
  EXPECT_EQ(summary["texels"], 96);
  EXPECT_EQ(summary["clusters"][0]["size"], 48);
  EXPECT_EQ(summary["clusters"][1]["size"], 48);
  EXPECT_GT(summary["pca"]["explained_variance_ratio"].get<double>(), 0.5);
  EXPECT_TRUE(summary["seconds"].contains("total"));
  EXPECT_EQ(summary["space"], clusteringSpaceName(kDefaultClusteringSpace));
  // 96 texels are far too few for PCA to sample (cluster/pca.h); the budget is recorded.
  EXPECT_EQ(summary["pca"]["sampled_texels"], 0);
  EXPECT_EQ(summary["pca"]["sample_mib"], PcaOptions().sampleBytes >> 20);
  EXPECT_EQ(output.find("sampled texels"), std::string::npos) << output;

  // Either space finds the two materials: the same halves, recorded as such.
  for (const char* space : {"linear", "log"}) {
    fs::path dir = root_ / space;
    code = run((root_ / "stack").string() + " --clusters 2 --components 2 --cluster-space " + space + " -q -o " + dir.string(),
               output);
    ASSERT_EQ(code, 0) << output;
    Image8 spaceLabels = readImage8((dir / "labels.png").string());
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 12; ++x)
        EXPECT_EQ(labelFromColour(&spaceLabels.rgb[3 * (y * 12 + x)]) == labelFromColour(&spaceLabels.rgb[0]), x < 6)
            << space << " " << x << "," << y;
    const nlohmann::json spaceSummary = nlohmann::json::parse(std::ifstream(dir / "summary.json"));
    EXPECT_EQ(spaceSummary["space"], space);
    EXPECT_EQ(spaceSummary["pca"]["space"],
              std::string(space) == "linear" ? "linear ABRDFs / alpha" : "standardized log(x + 1) ABRDFs");
    // The explained variance says which values it is of.
    const std::string values = std::string(space) == "linear" ? "linear ABRDFs / alpha" : "standardized log ABRDFs";
    EXPECT_NE(output.find("of the variance of the " + values + " ("), std::string::npos) << output;
  }
  code = run((root_ / "stack").string() + " --clusters 2 --cluster-space srgb -q -o " + (root_ / "bad").string(), output);
  EXPECT_EQ(code, 1);
  EXPECT_NE(output.find("--cluster-space: expected log or linear, got 'srgb'"), std::string::npos) << output;
  EXPECT_FALSE(fs::exists(root_ / "bad"));
}

TEST_F(ClusterCliTest, MemoryLimitRefusesBeforeLoadingAndThePeakIsReported) {
  fs::path out = root_ / "out";
  std::string output;
  EXPECT_EQ(run((root_ / "stack").string() + " --clusters 2 --components 2 -q --memory-limit 64M -o " + out.string(),
                output), 1);
  EXPECT_NE(output.find("--memory-limit 64M allows 64 MiB"), std::string::npos) << output;
  EXPECT_NE(output.find("12 x 8 texels x 4 images (8-bit)"), std::string::npos) << output;
  EXPECT_FALSE(fs::exists(out));
  EXPECT_EQ(run((root_ / "stack").string() + " --clusters 2 --components 2 -q --memory-limit 4G -o " + out.string(),
                output), 0) << output;
  EXPECT_NE(output.find("memory       peak"), std::string::npos) << output;
  std::ifstream in(out / "summary.json");
  nlohmann::json summary = nlohmann::json::parse(in);
  EXPECT_GT(summary["peak_memory_bytes"].get<double>(), 1e6);
}

// --stack-storage file: the same clusters from a stack in an unnamed scratch file, nothing left
// in the folder it was made in (the output folder's nearest existing parent by default).
TEST_F(ClusterCliTest, AStackInAScratchFileGivesTheSameClusters) {
  std::string output;
  const std::string args = (root_ / "stack").string() + " --clusters 2 --components 2 -q -o ";
  ASSERT_EQ(run(args + (root_ / "memory").string() + " --stack-storage memory", output), 0) << output;
  fs::create_directories(root_ / "scratch");
  ASSERT_EQ(run(args + (root_ / "scratch" / "file").string() + " --stack-storage file", output), 0) << output;
  EXPECT_EQ(readFileBytes((root_ / "scratch" / "file" / "labels.png").string()),
            readFileBytes((root_ / "memory" / "labels.png").string()));
  std::vector<fs::path> left;
  for (const auto& e : fs::directory_iterator(root_ / "scratch")) left.push_back(e.path());
  EXPECT_EQ(left, std::vector<fs::path>{root_ / "scratch" / "file"});
  EXPECT_EQ(run(args + (root_ / "x").string() + " --stack-storage file --scratch-dir " + (root_ / "none").string(),
                output), 1);
  EXPECT_NE(output.find((root_ / "none").string() + ": --scratch-dir: not a folder"), std::string::npos) << output;
}

TEST_F(ClusterCliTest, CropIsApplied) {
  std::string output;
  fs::path out = root_ / "crop";
  int code = run((root_ / "stack").string() + " --clusters 3 --components 2 --crop 4,2,4,4 -q -o " + out.string(),
                 output);
  ASSERT_EQ(code, 0) << output;
  Image8 labels = readImage8((out / "labels.png").string());
  EXPECT_EQ(labels.width, 4);
  EXPECT_EQ(labels.height, 4);
}

TEST_F(ClusterCliTest, BadClusterCountsFailClearlyAndWriteNothing) {
  std::string output;
  fs::path out = root_ / "bad";
  EXPECT_EQ(run((root_ / "stack").string() + " --clusters 500 -q -o " + out.string(), output), 1);
  EXPECT_NE(output.find("only 96 texels"), std::string::npos) << output;
  EXPECT_FALSE(fs::exists(out)) << "a failed data check left the output folder behind";

  EXPECT_EQ(run((root_ / "stack").string() + " --clusters 0 -q -o " + out.string(), output), 1);
  EXPECT_NE(output.find("--clusters must be at least 1"), std::string::npos) << output;

  EXPECT_EQ(run((root_ / "stack").string() + " --clusters 2 --components 13 -q -o " + out.string(), output), 1);
  EXPECT_NE(output.find("--components 13"), std::string::npos) << output;

  EXPECT_EQ(run((root_ / "stack").string() + " --clusters 2 --pca-sample -1 -q -o " + out.string(), output), 1);
  EXPECT_NE(output.find("--pca-sample must be >= 0"), std::string::npos) << output;

  EXPECT_EQ(run((root_ / "missing").string() + " --clusters 2 -q -o " + out.string(), output), 1);
  EXPECT_NE(output.find("missing"), std::string::npos) << output;
  EXPECT_FALSE(fs::exists(out));
}

}  // namespace
}  // namespace nbtf
