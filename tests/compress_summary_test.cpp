// The compress run's summary (pipeline/compress_summary.cpp): the stats as JSON with the documented keys, and as text.
#include <gtest/gtest.h>

#include <string>
#include <utility>

#include <nlohmann/json.hpp>

#include "compressor_fixtures.h"
#include "pipeline/compressor.h"

namespace nbtf {
namespace {

using testing::contains;
using testing::quickOptions;

TEST(Compressor, StatsJsonHasTheDocumentedKeys) {
  testing::TestMaterial m = testing::makeTestMaterial();
  CompressOptions o = quickOptions(4);
  o.train.epochs = 5;
  CompressStats stats;
  compressStack(m.stack, o, stats);
  nlohmann::json j = nlohmann::json::parse(compressStatsJson(stats));
  for (const char* key : {"rmse_train", "rmse_holdout", "ratio", "bytes", "seconds"}) EXPECT_TRUE(j.contains(key)) << key;
  for (const char* key : {"decoder", "latents", "ids", "total", "raw_float32"}) EXPECT_TRUE(j["bytes"].contains(key)) << key;
  for (const char* key : {"load", "preprocess", "cluster", "train", "assemble", "write"})
    EXPECT_TRUE(j["seconds"].contains(key)) << key;
  // The cluster stage's parts, as the stats hold them (their values are timings: not checked).
  const StageSeconds& t = stats.seconds;
  const std::pair<const char*, double> parts[] = {{"pca", t.clusterParts.pca},
                                                  {"kmeans", t.clusterParts.kmeans},
                                                  {"medians", t.clusterParts.medians},
                                                  {"coefficients", t.clusterParts.coefficients}};
  ASSERT_EQ(j["seconds"]["cluster_parts"].size(), 4u);
  for (const auto& [key, value] : parts) EXPECT_EQ(j["seconds"]["cluster_parts"][key].get<double>(), value) << key;
  // The training steps' phases, likewise; the steps ran, so the decoder's part is counted.
  const std::pair<const char*, double> trainParts[] = {{"sampling", t.trainParts.sampling},
                                                       {"encoder", t.trainParts.encoder},
                                                       {"decoder", t.trainParts.decoder},
                                                       {"optimizer", t.trainParts.optimizer}};
  ASSERT_EQ(j["seconds"]["train_parts"].size(), 4u);
  for (const auto& [key, value] : trainParts)
    EXPECT_EQ(j["seconds"]["train_parts"][key].get<double>(), value) << key;
  EXPECT_GT(t.trainParts.decoder, 0);
  EXPECT_EQ(j["seconds"]["assemble"].get<double>(), t.assemble);
  EXPECT_EQ(j["seconds"]["total"].get<double>(), t.total());
  EXPECT_GE(j["kmeans_iterations"].get<int>(), 1);
  EXPECT_EQ(j["kmeans_iterations"].get<int>(), stats.kmeansIterations);
  EXPECT_TRUE(j["rmse_holdout"].is_null());  // no hold-out set
  EXPECT_EQ(j["bytes"]["total"].get<std::uint64_t>(), stats.sizes.total);
  EXPECT_DOUBLE_EQ(j["ratio"].get<double>(), stats.sizes.ratio);
  std::string summary = formatCompressSummary(stats);
  EXPECT_TRUE(contains(summary, "on linear RGB / alpha")) << summary;
  EXPECT_TRUE(contains(summary, "ratio")) << summary;
  EXPECT_TRUE(contains(summary, "  train: decoder ")) << summary;
}

// Stats filled by hand: the JSON holds them as given, -1 (not measured) as null, a PCA file's
// bytes by its own parts, and the text names the default cluster count the input capped.
TEST(CompressSummary, JsonAndTextShowTheStatsAsGiven) {
  CompressStats s;
  s.method = CodecMethod::ClusteredNeural;
  s.output = "out.nbtf";
  s.texels = 640;
  s.clusters = 64;
  s.clustersConfigured = 1000;
  s.rmseTrain = 0.125;
  s.rmseHoldout = -1;
  s.sizes.total = 4096;
  s.sizes.ratio = 12.5;
  const nlohmann::json j = nlohmann::json::parse(compressStatsJson(s));
  EXPECT_EQ(j["method"], "clustered-neural");
  EXPECT_EQ(j["clusters"], 64);
  EXPECT_EQ(j["clusters_configured"], 1000);
  EXPECT_EQ(j["rmse_train"].get<double>(), 0.125);
  EXPECT_TRUE(j["rmse_holdout"].is_null());
  EXPECT_EQ(j["bytes"]["total"].get<std::uint64_t>(), 4096u);
  EXPECT_FALSE(j["bytes"].contains("pca_basis"));
  EXPECT_EQ(j["ratio"].get<double>(), 12.5);
  EXPECT_TRUE(j["adaptive"].is_null());
  EXPECT_TRUE(j["seconds"].contains("cluster_parts"));  // one fixed-k clustering
  EXPECT_FALSE(j["seconds"].contains("train_parts"));   // no steps ran
  const std::string text = formatCompressSummary(s);
  EXPECT_TRUE(contains(text, "summary: out.nbtf (clustered-neural, k = 64: the config's 1000 capped to one cluster "
                             "per 10 of the 640 texels)"))
      << text;

  CompressStats pca;
  pca.method = CodecMethod::Pca;
  pca.pcaComponents = 8;
  pca.sizes.pcaBasis = 100;
  const nlohmann::json p = nlohmann::json::parse(compressStatsJson(pca));
  EXPECT_EQ(p["bytes"]["pca_basis"], 100);
  EXPECT_FALSE(p["bytes"].contains("decoder"));
  EXPECT_TRUE(p["clusters_configured"].is_null());
  EXPECT_TRUE(contains(formatCompressSummary(pca), "(pca, C = 8 components)")) << formatCompressSummary(pca);
}

}  // namespace
}  // namespace nbtf
