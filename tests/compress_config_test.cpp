#include "pipeline/compress_config.h"

#include <gtest/gtest.h>
#include <iterator>
#include <fstream>
#include <filesystem>
#include <algorithm>
#include <functional>

#include <nlohmann/json.hpp>

#include "model/config/config_section.h"
#include "test_util.h"
#include "util/atomic_file.h"

namespace nbtf {
namespace {

std::string writeConfig(const test::TempDir& dir, const std::string& text) {
  writeFileAtomic(dir / "config.json", text);
  return dir / "config.json";
}

TEST(CompressConfig, ReadsTheAdaptiveObjectBesideTheRecipe) {
  test::TempDir dir;
  const std::string path = writeConfig(dir, R"({"training": {"epochs": 7},
    "adaptive": {"enabled": true, "target_rmse": 0.03, "max_clusters": 900, "size_budget": 60000,
                 "initial_clusters": 40, "stages": 4, "growth_fraction": 0.5, "merge_tolerance": 0.01}})");
  CompressConfig c = loadCompressConfig(path);
  EXPECT_EQ(c.train.epochs, 7);
  EXPECT_TRUE(c.adaptive.enabled);
  EXPECT_DOUBLE_EQ(c.adaptive.targetRmse, 0.03);
  EXPECT_EQ(c.adaptive.maxClusters, 900);
  EXPECT_EQ(c.adaptive.sizeBudget, 60000u);
  EXPECT_EQ(c.adaptive.initialClusters, 40);
  EXPECT_EQ(c.adaptive.stages, 4);
  EXPECT_DOUBLE_EQ(c.adaptive.growthFraction, 0.5);
  EXPECT_DOUBLE_EQ(c.adaptive.mergeTolerance, 0.01);

  // What a file records is a config that loads back to the same settings.
  const std::string recorded =
      writeConfig(dir, "{\"adaptive\": " + adaptiveConfigJson(c.adaptive) + "}");
  CompressConfig again = loadCompressConfig(recorded);
  EXPECT_EQ(adaptiveConfigJson(again.adaptive), adaptiveConfigJson(c.adaptive));

  // Absent: off, with the defaults; the recipe alone is still a valid compress config.
  CompressConfig plain = loadCompressConfig(writeConfig(dir, R"({"training": {"epochs": 3}})"));
  EXPECT_FALSE(plain.adaptive.enabled);
  EXPECT_EQ(adaptiveConfigJson(plain.adaptive), adaptiveConfigJson(AdaptiveOptions{}));
}

// configs/adaptive.json is the default recipe with adaptive clusters on.
TEST(CompressConfig, ShippedAdaptiveConfigIsTheDefaultRecipePlusAdaptive) {
  const std::string dir = std::string(NBTF_SOURCE_DIR) + "/configs/";
  CompressConfig c = loadCompressConfig(dir + "adaptive.json");
  EXPECT_TRUE(c.adaptive.enabled);
  AdaptiveOptions expected;
  expected.enabled = true;
  EXPECT_EQ(adaptiveConfigJson(c.adaptive), adaptiveConfigJson(expected));
  EXPECT_EQ(trainConfigJson(c.train), trainConfigJson(loadTrainConfig(dir + "default.json")));
  EXPECT_EQ(c.clusters, loadCompressConfig(dir + "default.json").clusters);
  EXPECT_FALSE(loadCompressConfig(dir + "default.json").adaptive.enabled);
}

// The shipped configs of the rate-distortion curve are each another shipped config with a few
// keys changed and nothing else: `name` equals `base` after `change`.
void expectShippedConfigIs(const std::string& name, const std::string& base,
                           const std::function<void(TrainConfig&)>& change) {
  SCOPED_TRACE(name);
  const std::string dir = std::string(NBTF_SOURCE_DIR) + "/configs/";
  TrainConfig expected = loadTrainConfig(dir + base);
  change(expected);
  EXPECT_NE(trainConfigJson(expected), trainConfigJson(loadTrainConfig(dir + base)));  // the change changes something
  EXPECT_EQ(trainConfigJson(loadTrainConfig(dir + name)), trainConfigJson(expected));
}

// configs/compact.json: the default with a width-64 decoder and one modulation coefficient per
// texel, the small end of the curve.
TEST(CompressConfig, ShippedCompactConfigIsTheDefaultWithASmallerDecoderAndModulation) {
  expectShippedConfigIs("compact.json", "default.json", [](TrainConfig& c) {
    c.model.decoderWidth = 64;
    c.modulation.channels = 1;
  });
}

// configs/high_fidelity.json: the default with cluster planes (stored in 8 bits), three
// modulation terms and 128 images per encoder input (each cluster's planes visited 4x as
// often), the large end of the curve.
TEST(CompressConfig, ShippedHighFidelityConfigIsTheDefaultWithClusterPlanesAndThreeTerms) {
  expectShippedConfigIs("high_fidelity.json", "default.json", [](TrainConfig& c) {
    c.model.clusterPlaneFeatures = 8;
    c.model.clusterPlaneResolution = 6;
    c.storage.clusterPlanes = "8bit";
    c.modulation.terms = 3;
    c.imagesPerInput = 128;
  });
}

// configs/close_up.json: high_fidelity.json's recipe (its k differs: one cluster per 2.5 texels,
// checked beside the other configs' k below).
TEST(CompressConfig, ShippedCloseUpConfigIsHighFidelitysRecipe) {
  const std::string dir = std::string(NBTF_SOURCE_DIR) + "/configs/";
  EXPECT_EQ(trainConfigJson(loadTrainConfig(dir + "close_up.json")), trainConfigJson(loadTrainConfig(dir + "high_fidelity.json")));
}

// configs/balanced.json: high_fidelity.json with small cluster planes (4 x 4 points x 2
// features), the middle of the curve.
TEST(CompressConfig, ShippedBalancedConfigIsHighFidelityWithSmallClusterPlanes) {
  expectShippedConfigIs("balanced.json", "high_fidelity.json", [](TrainConfig& c) {
    c.model.clusterPlaneResolution = 4;
    c.model.clusterPlaneFeatures = 2;
  });
}

TEST(CompressConfig, BadAdaptiveValuesNameTheFileAndTheKey) {
  test::TempDir dir;
  const std::vector<std::pair<std::string, std::string>> cases = {
      {R"({"adaptive": {"stage": 3}})", "'adaptive.stage' unknown key"},
      {R"({"adaptive": {"enabled": 1}})", "'adaptive.enabled' must be true or false"},
      {R"({"adaptive": {"stages": 0}})", "'adaptive.stages' (--stages) must be in 1..20, got 0"},
      {R"({"adaptive": {"max_clusters": -2}})", "'adaptive.max_clusters' (--max-clusters) must be >= 0"},
      {R"({"adaptive": {"size_budget": -1}})", "'adaptive.size_budget' must be a non-negative integer"},
      {R"({"adaptive": {"target_rmse": -0.1}})", "'adaptive.target_rmse' (--target-rmse) must be a number >= 0"},
      {R"({"adaptive": {"growth_fraction": 1}})", "'adaptive.growth_fraction' must be in (0, 1)"},
      {R"({"adaptive": {"merge_tolerance": -1}})", "'adaptive.merge_tolerance' must be a number >= 0"},
      {R"({"adaptive": 5})", "'adaptive' must be an object"},
      {R"({"adaptiv": {}})", "'adaptiv' unknown key (expected model, direction_planes, cluster_planes, optimizer, training, modulation, storage, clustering, adaptive)"},
      {R"({"model": {"latent_dim": 0}, "adaptive": {}})", "'model.latent_dim' must be in 1..4096"},
  };
  for (const auto& [text, message] : cases) {
    const std::string path = writeConfig(dir, text);
    test::expectErrorContaining([&] { loadCompressConfig(path); }, {path + ": ", message});
  }
  // The training recipe's own loader skips the objects only compress reads, so that one file
  // serves both, and still names a key no loader reads.
  const std::string path = writeConfig(dir, R"({"adaptive": {"enabled": true}, "clustering": {"space": "linear"},
                                              "training": {"epochs": 5}})");
  EXPECT_EQ(loadTrainConfig(path).epochs, 5);
  const std::string typo = writeConfig(dir, R"({"adaptiv": {"enabled": true}})");
  test::expectErrorContaining([&] { loadTrainConfig(typo); },
                              {typo, "'adaptiv' unknown key (expected model, direction_planes, cluster_planes, optimizer, "
                                     "training, modulation, storage, clustering, adaptive)"});
}

TEST(CompressConfig, ReadsTheClusteringSpace) {
  test::TempDir dir;
  EXPECT_EQ(loadCompressConfig(writeConfig(dir, R"({"clustering": {"space": "linear"}})")).clusteringSpace,
            ClusteringSpace::Linear);
  EXPECT_EQ(loadCompressConfig(writeConfig(dir, R"({"clustering": {"space": "log"}})")).clusteringSpace,
            ClusteringSpace::Log);
  EXPECT_EQ(loadCompressConfig(writeConfig(dir, R"({"training": {"epochs": 3}})")).clusteringSpace,
            kDefaultClusteringSpace);
  EXPECT_EQ(CompressOptions{}.clusteringSpace, kDefaultClusteringSpace);
  const std::vector<std::pair<std::string, std::string>> cases = {
      {R"({"clustering": {"space": "srgb"}})", "'clustering.space': expected log or linear, got 'srgb'"},
      {R"({"clustering": {"space": 1}})", "'clustering.space' must be a string"},
      {R"({"clustering": {"spaces": "log"}})", "'clustering.spaces' unknown key"},
  };
  for (const auto& [text, message] : cases) {
    const std::string path = writeConfig(dir, text);
    test::expectErrorContaining([&] { loadCompressConfig(path); }, {path + ": ", message});
  }
  EXPECT_STREQ(clusteringSpaceName(ClusteringSpace::Linear), "linear");
  EXPECT_EQ(parseClusteringSpace("log", "--cluster-space"), ClusteringSpace::Log);
  test::expectErrorContaining([] { parseClusteringSpace("Linear", "--cluster-space"); },
                              {"--cluster-space: expected log or linear, got 'Linear'"});
}

TEST(CompressConfig, ReadsTheDefaultClusterCount) {
  test::TempDir dir;
  EXPECT_EQ(loadCompressConfig(writeConfig(dir, R"({"clustering": {"clusters": 250}})")).clusters, 250);
  EXPECT_EQ(loadCompressConfig(writeConfig(dir, R"({"clustering": {"clusters": 0}})")).clusters, 0);
  EXPECT_EQ(loadCompressConfig(writeConfig(dir, R"({"training": {"epochs": 3}})")).clusters, kDefaultClusters);
  const std::vector<std::pair<std::string, std::string>> cases = {
      {R"({"clustering": {"clusters": -1}})", "'clustering.clusters' must be >= 0 (the default k; 0 = per-texel), got -1"},
      {R"({"clustering": {"clusters": "many"}})", "'clustering.clusters'"},
  };
  for (const auto& [text, message] : cases) {
    const std::string path = writeConfig(dir, text);
    test::expectErrorContaining([&] { loadCompressConfig(path); }, {path + ": ", message});
  }
  // k from the input's size: a number >= 1, and not beside a fixed k.
  EXPECT_EQ(loadCompressConfig(writeConfig(dir, R"({"clustering": {"texels_per_cluster": 4}})")).texelsPerCluster, 4);
  const std::vector<std::pair<std::string, std::string>> perTexel = {
      {R"({"clustering": {"texels_per_cluster": 0.5}})", "'clustering.texels_per_cluster' must be a number >= 1 (k = texels / it), got 0.5"},
      {R"({"clustering": {"texels_per_cluster": -3}})", "'clustering.texels_per_cluster' must be a number >= 1"},
      {R"({"clustering": {"texels_per_cluster": 2, "clusters": 100}})", "'clustering' gives both 'clusters' and 'texels_per_cluster'"},
  };
  for (const auto& [text, message] : perTexel) {
    const std::string path = writeConfig(dir, text);
    test::expectErrorContaining([&] { loadCompressConfig(path); }, {path + ": ", message});
  }
  // The named points of the curve each carry their k (close_up: from the input's size).
  EXPECT_EQ(loadCompressConfig("close_up").texelsPerCluster, 2.5);
  EXPECT_EQ(loadCompressConfig("high_fidelity").texelsPerCluster, 0);
  EXPECT_EQ(loadCompressConfig("compact").clusters, 250);
  EXPECT_EQ(loadCompressConfig("high_fidelity").clusters, 500);
  EXPECT_EQ(loadCompressConfig("default").clusters, 1000);
}

TEST(CompressConfig, AdaptiveOptionsAreCheckedWhereverTheyComeFrom) {
  AdaptiveOptions a;
  EXPECT_NO_THROW(validateAdaptiveOptions(a, "command line"));
  a.stages = 21;
  test::expectErrorContaining([&] { validateAdaptiveOptions(a, "command line"); },
                              {"command line: 'adaptive.stages' (--stages) must be in 1..20, got 21"});
  a = AdaptiveOptions{};
  a.initialClusters = -1;
  test::expectErrorContaining([&] { validateAdaptiveOptions(a, "x.json + command line"); },
                              {"x.json + command line: 'adaptive.initial_clusters' (--initial-clusters)"});
}

}  // namespace
}  // namespace nbtf
