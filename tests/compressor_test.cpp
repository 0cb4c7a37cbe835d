#include "pipeline/compressor.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <tuple>
#include <utility>
#include <unistd.h>
#include <nlohmann/json.hpp>

#include "codec/decoder.h"
#include "codec/nbtf_describe.h"
#include "codec/nbtf_file.h"
#include "codec_fixtures.h"
#include "compressor_fixtures.h"
#include "io/btf_loader.h"
#include "io/ubo2014_btf.h"
#include "model/config/config_section.h"
#include "pipeline/compress_config.h"
#include "preprocess/ubo2014_factorize.h"
#include "support/mlp_reference.h"
#include "test_util.h"
#include "util/atomic_file.h"
#include "util/error.h"

namespace nbtf {
namespace {
namespace fs = std::filesystem;

using testing::contains;
using testing::quickOptions;

// The RMSE of the written file itself, decoded texel by texel with its own decoder: what a
// user of the file gets, independent of the trainer's bookkeeping.
double fileRmse(const CompressedBtf& b, const BtfStack& stack, const std::vector<int>& images) {
  double sse = 0;
  const int dirInputs = b.directionInputs();  // the fixed encoding's and the direction planes'
  RowMatrix in(static_cast<Eigen::Index>(images.size()), b.latentDim + dirInputs);
  for (int t = 0; t < b.numTexels(); ++t) {
    const float* z = b.latentOfTexel(t);
    for (std::size_t j = 0; j < images.size(); ++j) {
      for (int d = 0; d < b.latentDim; ++d) in(j, d) = z[d];
      const DirectionInput dirs =
          decoderDirectionInput(b, b.lights[images[j] / b.views.size()], b.views[images[j] % b.views.size()]);
      for (int q = 0; q < dirInputs; ++q) in(j, b.latentDim + q) = dirs[q];
    }
    RowMatrix out = mlpForward(b.decoder, in);
    for (std::size_t j = 0; j < images.size(); ++j)
      for (int c = 0; c < 3; ++c) sse += std::pow(out(j, c) - stack.sample(images[j], t, c) / b.alpha, 2);
  }
  return std::sqrt(sse / (3.0 * b.numTexels() * images.size()));
}

std::vector<int> allImages(const BtfStack& s) {
  std::vector<int> v(s.numImages());
  for (int i = 0; i < s.numImages(); ++i) v[i] = i;
  return v;
}

// The best a clustered file with these ids can do: every texel predicted by its cluster's
// exact mean (one latent per cluster cannot represent the spread inside a cluster).
double clusterMeanRmse(const BtfStack& stack, float alpha, const std::vector<std::int32_t>& ids, int k) {
  const int M = stack.numTexels();
  std::vector<float> rgb(static_cast<std::size_t>(M) * 3);
  double sse = 0;
  for (int i = 0; i < stack.numImages(); ++i) {
    stack.imageLinear(i, rgb.data());
    std::vector<double> sum(3 * k, 0.0), count(k, 0.0);
    for (int t = 0; t < M; ++t) {
      count[ids[t]] += 1;
      for (int c = 0; c < 3; ++c) sum[3 * ids[t] + c] += rgb[3 * t + c] / alpha;
    }
    for (int t = 0; t < M; ++t)
      for (int c = 0; c < 3; ++c) sse += std::pow(rgb[3 * t + c] / alpha - sum[3 * ids[t] + c] / count[ids[t]], 2);
  }
  return std::sqrt(sse / (3.0 * M * stack.numImages()));
}

TEST(Compressor, ClusteredMaterialBeatsTheImageMeanAndRoundTrips) {
  testing::TestMaterial m = testing::makeTestMaterial();
  CompressStats stats;
  CompressOptions o = quickOptions(6);
  o.train.epochs = 600;  // an epoch is only 6 clusters x 81 images here
  CompressedBtf b = compressStack(m.stack, o, stats);
  EXPECT_EQ(b.method, CodecMethod::ClusteredNeural);
  EXPECT_EQ(b.latentRows, 6);
  ASSERT_EQ(b.ids.size(), 64u);
  EXPECT_EQ(b.numImages(), 81);
  EXPECT_FLOAT_EQ(b.alpha, m.alpha);
  // The trainer's figure is the file's figure, and clearly below predicting each image's mean.
  double decoded = fileRmse(b, m.stack, allImages(m.stack));
  EXPECT_NEAR(stats.rmseTrain, decoded, 1e-4);
  double floor = clusterMeanRmse(m.stack, b.alpha, b.ids, 6), baseline = testing::imageMeanRmse(m);
  EXPECT_LT(floor, 0.6 * baseline);  // k-means found the material's structure
  EXPECT_LT(decoded, floor + 0.15 * (baseline - floor)) << "floor " << floor << ", image-mean " << baseline;
  // Sizes are the file's: 24,383 decoder parameters and (16 + 12) x 106 more for the
  // default's two-octave Fourier direction inputs and direction planes, the planes' 3 x 8 x 8
  // x 4 values, 6 x 8 latents, 64 one-byte ids.
  EXPECT_EQ(stats.sizes.decoder, (24383u + 28 * 106) * 4);
  EXPECT_EQ(stats.sizes.planes, 3u * 8 * 8 * 4 * 4);
  EXPECT_EQ(stats.sizes.latents, 6u * 8 * 4);
  EXPECT_EQ(stats.sizes.ids, 64u);
  EXPECT_EQ(stats.sizes.rawFloat32, 64u * 81 * 12);
  std::vector<std::uint8_t> bytes = serializeNbtf(b);
  CompressedBtf back = parseNbtf(bytes.data(), bytes.size(), "mem");
  EXPECT_EQ(serializeNbtf(back), bytes);
  nlohmann::json meta = nlohmann::json::parse(back.metadataJson);
  EXPECT_EQ(meta["training"]["rmse_train"].get<double>(), stats.rmseTrain);
  EXPECT_EQ(meta["clustering"]["k"].get<int>(), 6);
  EXPECT_EQ(meta["config"]["optimizer"]["name"], "adam");
  // Without modulation the recorded modulation object is the one files had before the
  // per-channel default (whatever channels and mean_weight say), so the paper's files keep
  // their bytes.
  EXPECT_EQ(meta["config"]["modulation"], nlohmann::json::parse(R"({"mode": "none", "terms": 1, "bits": 6})"));
  // What eval checks a reference against: the source's per-image means.
  ASSERT_TRUE(meta["source"].contains("fingerprint"));
  EXPECT_EQ(meta["source"]["fingerprint"]["images"].size(), 32u);
  // The stats say the PCA components used (the default, capped by the data), as `info` does.
  EXPECT_EQ(stats.pcaComponents, 32);
  EXPECT_EQ(meta["clustering"]["pca_components"].get<int>(), stats.pcaComponents);
  EXPECT_EQ(nlohmann::json::parse(compressStatsJson(stats))["pca_components"].get<int>(), 32);
}

// The RMSE of `b` over every image of `stack`, decoded image by image by the file's decoder.
double decodedFileRmse(const CompressedBtf& b, const BtfStack& stack) {
  NbtfDecoder dec(b);
  std::vector<float> img(3 * static_cast<std::size_t>(b.numTexels()));
  double sse = 0;
  for (int i = 0; i < stack.numImages(); ++i) {
    dec.decodeImage(b.lights[i / b.views.size()], b.views[i % b.views.size()], img.data(), OutputScale::Normalized);
    for (int t = 0; t < b.numTexels(); ++t)
      for (int c = 0; c < 3; ++c) sse += std::pow(img[3 * t + c] - stack.sample(i, t, c) / b.alpha, 2);
  }
  return std::sqrt(sse / (3.0 * b.numTexels() * stack.numImages()));
}

// Two compressions of one stack whose options differ only in how the result is stored (what
// `change` sets): the training is the same bit for bit, checked here.
struct StoredTwice {
  CompressedBtf first, second;
  CompressStats firstStats, secondStats;
};
StoredTwice compressStoredTwice(const BtfStack& stack, CompressOptions o,
                                const std::function<void(CompressOptions&)>& change) {
  StoredTwice run;
  run.first = compressStack(stack, o, run.firstStats);
  change(o);
  run.second = compressStack(stack, o, run.secondStats);
  EXPECT_EQ(run.second.decoder.layers[0].weight, run.first.decoder.layers[0].weight);
  return run;
}

// Cluster planes stored in 8 bits (format 1.10): the same training as with float32 planes, a
// file whose reported RMSE is its own (measured through the codes) and close to the float one,
// and a recorded recipe that says so.
TEST(Compressor, EightBitClusterPlanesAreMeasuredAsStored) {
  testing::TestMaterial m = testing::makeTestMaterial();
  CompressOptions o = quickOptions(6);
  o.train.epochs = 300;
  o.train.model.clusterPlaneResolution = 4;
  o.train.model.clusterPlaneFeatures = 2;
  const StoredTwice run =
      compressStoredTwice(m.stack, o, [](CompressOptions& c) { c.train.storage.clusterPlanes = "8bit"; });
  const CompressedBtf &floats = run.first, &eight = run.second;
  const CompressStats &floatStats = run.firstStats, &eightStats = run.secondStats;
  EXPECT_FALSE(floats.storage.clusterPlanes8Bit);
  ASSERT_TRUE(eight.storage.clusterPlanes8Bit);
  EXPECT_NE(eight.clusterPlanes.values, floats.clusterPlanes.values);
  EXPECT_EQ(serializeNbtf(floats)[10], 9);
  const std::vector<std::uint8_t> bytes = serializeNbtf(eight);
  EXPECT_EQ(bytes[10], 10);
  const CompressedBtf back = parseNbtf(bytes.data(), bytes.size(), "mem");
  EXPECT_EQ(back.clusterPlanes.values, eight.clusterPlanes.values);
  EXPECT_NEAR(eightStats.rmseTrain, decodedFileRmse(back, m.stack), 1e-5);
  EXPECT_NEAR(floatStats.rmseTrain, decodedFileRmse(floats, m.stack), 1e-4);
  EXPECT_LT(eightStats.rmseTrain, 1.05 * floatStats.rmseTrain);
  EXPECT_EQ(eightStats.sizes.clusterPlanes, 6u * (3 * 4 * 4 * 2 + 2 * 8));
  const nlohmann::json recorded = nlohmann::json::parse(back.metadataJson)["config"];
  EXPECT_EQ(recorded["storage"]["cluster_planes"], "8bit");
  EXPECT_FALSE(nlohmann::json::parse(floats.metadataJson)["config"]["storage"].contains("cluster_planes"));
}

// Decorrelated modulation codes (format 1.11, the default): the same training as linear codes, a
// file whose reported RMSE is its own and about the linear file's, and a recorded recipe that
// says which.
TEST(Compressor, DecorrelatedCodesAreMeasuredAsStored) {
  testing::TestMaterial m = testing::makeTestMaterial();
  CompressOptions o = quickOptions(4);
  o.train.epochs = 300;
  o.train.modulation = ModulationConfig{"svd", 1, 6};
  o.train.modulation.channels = 3;
  o.train.modulation.codes = "linear";
  const StoredTwice run =
      compressStoredTwice(m.stack, o, [](CompressOptions& c) { c.train.modulation.codes = "decorrelated"; });
  EXPECT_FALSE(run.first.modulation.decorrelated);
  ASSERT_TRUE(run.second.modulation.decorrelated);
  EXPECT_LT(serializeNbtf(run.first)[10], 11);
  const std::vector<std::uint8_t> bytes = serializeNbtf(run.second);
  EXPECT_EQ(bytes[10], 11);
  const CompressedBtf back = parseNbtf(bytes.data(), bytes.size(), "mem");
  EXPECT_NEAR(run.secondStats.rmseTrain, decodedFileRmse(back, m.stack), 1e-5);
  // The decorrelated file's RMSE (a deterministic value of the same training, not a time) stays
  // about the linear file's: first linear, second decorrelated.
  EXPECT_LT(run.secondStats.rmseTrain, 1.02 * run.firstStats.rmseTrain);
  EXPECT_EQ(nlohmann::json::parse(back.metadataJson)["config"]["modulation"]["codes"], "decorrelated");
  EXPECT_EQ(nlohmann::json::parse(run.first.metadataJson)["config"]["modulation"]["codes"], "linear");
}

// Per-texel modulation with compact storage: the file decodes (through its own decoder, every
// texel) to the RMSE the compressor reports, below the plain cluster-mean floor on a material
// whose texels differ by brightness, and its parts are stored compactly.
TEST(Compressor, ModulatedCompactFileBeatsTheClusterFloor) {
  auto m = testing::makeTestMaterial();
  // The third run stores the decoder with 8-bit weights: measured through them too; the fourth
  // has one coefficient per channel (format 1.5).
  struct Run {
    int terms;
    const char* decoderStorage;
    int channels;
  };
  for (auto [terms, decoderStorage, channels] : {Run{1, "half", 1}, Run{2, "half", 1}, Run{1, "int8", 1}, Run{1, "int8", 3}}) {
    SCOPED_TRACE("terms " + std::to_string(terms) + ", channels " + std::to_string(channels));
    const bool int8 = std::string(decoderStorage) == "int8";
    CompressOptions o = quickOptions(4);
    o.train.modulation = ModulationConfig{"svd", terms, 6};
    o.train.modulation.channels = channels;
    o.train.storage = StorageConfig{decoderStorage, "half", "zstd", "zstd", "zstd"};
    o.train.holdoutFraction = 0.1;
    o.train.epochs = 1200;  // one step per epoch here: the terms need more steps than the quick recipe
    CompressStats stats;
    CompressedBtf b = compressStack(m.stack, o, stats);
    ASSERT_EQ(b.modulation.terms, terms);
    ASSERT_EQ(b.modulation.channels, channels);
    EXPECT_EQ(stats.modulationChannels, channels);
    // The file's metadata records what ran, also where it is not today's default (channels 1).
    const nlohmann::json recorded = nlohmann::json::parse(b.metadataJson)["config"]["modulation"];
    EXPECT_EQ(recorded["channels"].get<int>(), channels);
    EXPECT_EQ(recorded["mean_weight"].get<double>(), o.train.modulation.meanWeight);
    EXPECT_EQ(b.decoder.outputSize(), 3 * terms);
    EXPECT_TRUE(b.storage.decoderHalf != int8 && b.storage.decoderInt8 == int8 && b.storage.latentsHalf &&
                b.storage.idsZstd && b.storage.metadataZstd);
    const double floor = clusterMeanRmse(m.stack, m.alpha, b.ids, 4);
    EXPECT_NEAR(stats.rmseFloor, floor, 0.1 * floor);  // over the training images there
    EXPECT_LT(stats.rmseFloorModulated, 0.2 * stats.rmseFloor);
    EXPECT_LT(stats.rmseTrain, 0.8 * floor) << "terms " << terms << "\n" << formatCompressSummary(stats);
    // The reported RMSE is the file's: decode every image with the file's decoder.
    std::vector<std::uint8_t> bytes = serializeNbtf(b);
    NbtfDecoder dec(parseNbtf(bytes.data(), bytes.size(), "mem"));
    double sse = 0;
    std::size_t count = 0;
    std::vector<float> img(3 * static_cast<std::size_t>(b.numTexels()));
    for (int i = 0; i < m.stack.numImages(); ++i) {
      if (std::binary_search(b.holdoutImages.begin(), b.holdoutImages.end(), i)) continue;
      dec.decodeImage(b.lights[i / b.views.size()], b.views[i % b.views.size()], img.data(), OutputScale::Normalized);
      for (int t = 0; t < b.numTexels(); ++t)
        for (int c = 0; c < 3; ++c) sse += std::pow(img[3 * t + c] - m.stack.sample(i, t, c) / b.alpha, 2), ++count;
    }
    EXPECT_NEAR(std::sqrt(sse / count), stats.rmseTrain, 1e-5);
    EXPECT_GT(stats.sizes.modulation, 0u);
    std::uint64_t outputs = 0;
    for (const DenseLayer& l : b.decoder.layers) outputs += l.out;
    EXPECT_EQ(stats.sizes.decoder, int8 ? b.decoder.parameterCount() + 3 * outputs : 2 * b.decoder.parameterCount());
  }
}

TEST(Compressor, PerTexelModeStoresOneLatentPerTexelAndNoIds) {
  testing::TestMaterial m = testing::makeTestMaterial();
  CompressStats stats;
  CompressOptions o = quickOptions(0);
  o.train.epochs = 60;
  CompressedBtf b = compressStack(m.stack, o, stats);
  EXPECT_EQ(b.method, CodecMethod::PerTexelNeural);
  EXPECT_EQ(b.latentRows, 64);
  EXPECT_TRUE(b.ids.empty());
  EXPECT_EQ(stats.sizes.ids, 0u);
  EXPECT_EQ(stats.pcaExplainedVarianceRatio, -1);
  double decoded = fileRmse(b, m.stack, allImages(m.stack));
  EXPECT_NEAR(stats.rmseTrain, decoded, 1e-4);
  EXPECT_LT(decoded, 0.3 * testing::imageMeanRmse(m));  // one latent per texel: no cluster floor
}

TEST(Compressor, SameSeedSameBytesOtherSeedOtherBytes) {
  testing::TestMaterial m = testing::makeTestMaterial();
  CompressStats s1, s2, s3;
  CompressOptions o = quickOptions(5);
  o.train.epochs = 20;
  std::vector<std::uint8_t> a = serializeNbtf(compressStack(m.stack, o, s1));
  std::vector<std::uint8_t> b = serializeNbtf(compressStack(m.stack, o, s2));
  EXPECT_EQ(a, b);
  o.train.seed = 2;
  EXPECT_NE(serializeNbtf(compressStack(m.stack, o, s3)), a);
}

// A UBO2014 file too large to expand stays factorized (its values computed when read): the
// compressed file must not depend on which of the two the loader chose.
TEST(Compressor, FactorizedUbo2014InputGivesTheSameFileAsTheExpandedOne) {
  testing::TestMaterial m = testing::makeTestMaterial();
  Ubo2014FactorizeOptions f;
  f.components = 6;
  f.progress = false;
  test::TempDir dir;
  const std::string path = dir / "material.btf";
  factorizeUbo2014(m.stack, f).write(path);
  LoadOptions load;
  load.progress = false;
  BtfStack stored = loadBtfStack(path, load);
  load.expandUpTo = 0;
  BtfStack computed = loadBtfStack(path, load);
  ASSERT_FALSE(stored.isComputed());
  ASSERT_TRUE(computed.isComputed());
  CompressOptions o = quickOptions(5);
  o.train.epochs = 20;
  CompressStats s1, s2;
  std::vector<std::uint8_t> a = serializeNbtf(compressStack(stored, o, s1));
  EXPECT_EQ(a, serializeNbtf(compressStack(computed, o, s2)));
  EXPECT_EQ(s1.rmseTrain, s2.rmseTrain);
  EXPECT_EQ(s1.rmseFloor, s2.rmseFloor);
}

TEST(Compressor, HoldoutImagesAreRecordedAndMeasured) {
  testing::TestMaterial m = testing::makeTestMaterial();
  CompressOptions o = quickOptions(6);
  o.train.holdoutFraction = 0.2;
  CompressStats stats;
  CompressedBtf b = compressStack(m.stack, o, stats);
  ASSERT_FALSE(b.holdoutImages.empty());
  EXPECT_EQ(stats.holdoutImages, static_cast<int>(b.holdoutImages.size()));
  EXPECT_TRUE(std::is_sorted(b.holdoutImages.begin(), b.holdoutImages.end()));
  EXPECT_NEAR(stats.rmseHoldout, fileRmse(b, m.stack, b.holdoutImages), 1e-4);
  std::vector<std::uint8_t> bytes = serializeNbtf(b);
  EXPECT_EQ(parseNbtf(bytes.data(), bytes.size(), "mem").holdoutImages, b.holdoutImages);
}

// 8 x 8 texels that differ in two ways: the left half is twice as bright as the right in
// every image, but dark (0.02 against 0.04); the top half has a highlight of 0.5 in four of
// the 36 images where the bottom half has 1.0.
BtfStack darkDetailOrHighlightStack() {
  std::vector<Direction> lights, views;
  for (int i = 0; i < 6; ++i) lights.push_back({12.0 * i, 50.0 * i});
  for (int i = 0; i < 6; ++i) views.push_back({10.0 * i, 70.0 * i});
  BtfStack stack(lights, views, 8, 8, SampleType::Srgb8);
  std::vector<float> rgb(8 * 8 * 3);
  for (int image = 0; image < stack.numImages(); ++image) {
    for (int t = 0; t < 64; ++t) {
      const int x = t % 8, y = t / 8;
      const float value = image < 4 ? (y < 4 ? 0.5f : 1.0f) : (x < 4 ? 0.04f : 0.02f);
      for (int c = 0; c < 3; ++c) rgb[3 * t + c] = value;
    }
    stack.setImageLinear(image, rgb.data());
  }
  return stack;
}

// Clusters found in the linear space follow the linear values' largest differences (the
// highlight, which dominates the error eq. 10 measures); the standardized log space's follow
// the most dimensions (the dark detail). The space is recorded in the stats, the file and `info`.
TEST(Compressor, LinearClusteringSpaceIsUsedAndRecorded) {
  const BtfStack stack = darkDetailOrHighlightStack();
  CompressOptions o = quickOptions(2);
  o.train.epochs = 5;
  CompressStats logStats, linearStats;
  o.clusteringSpace = ClusteringSpace::Log;
  const CompressedBtf logFile = compressStack(stack, o, logStats);
  o.clusteringSpace = ClusteringSpace::Linear;
  const CompressedBtf linearFile = compressStack(stack, o, linearStats);
  EXPECT_EQ(logStats.clusteringSpace, "log");
  EXPECT_EQ(linearStats.clusteringSpace, "linear");
  EXPECT_EQ(nlohmann::json::parse(compressStatsJson(linearStats))["clustering_space"], "linear");
  int splitByColumn = 0, splitByRow = 0;  // texel pairs that agree with the split
  for (int t = 0; t < 64; ++t) {
    splitByColumn += (logFile.ids[t] == logFile.ids[0]) == (t % 8 < 4);
    splitByRow += (linearFile.ids[t] == linearFile.ids[0]) == (t / 8 < 4);
  }
  EXPECT_EQ(splitByColumn, 64);
  EXPECT_EQ(splitByRow, 64);
  EXPECT_LT(clusterMeanRmse(stack, linearStats.alpha, linearFile.ids, 2),
            0.5 * clusterMeanRmse(stack, logStats.alpha, logFile.ids, 2));
  for (const auto& [file, space, described] :
       {std::make_tuple(&logFile, "log", "standardized log ABRDFs"),
        std::make_tuple(&linearFile, "linear", "linear ABRDFs / alpha")}) {
    const std::vector<std::uint8_t> bytes = serializeNbtf(*file);
    const CompressedBtf back = parseNbtf(bytes.data(), bytes.size(), "mem");
    EXPECT_EQ(nlohmann::json::parse(back.metadataJson)["clustering"]["space"], space);
    EXPECT_TRUE(contains(describeNbtf(back, "mem", bytes.size()), described)) << space;
  }
}

TEST(Compressor, PcaBaselineFillsTheSameStatsAndJson) {
  testing::TestMaterial m = testing::makeTestMaterial();
  CompressOptions o;
  o.pcaBaseline = true;
  o.pcaComponents = 3;
  o.train.holdoutFraction = 0.1;
  o.progress = false;
  CompressStats stats;
  CompressedBtf b = compressStack(m.stack, o, stats);
  EXPECT_EQ(b.method, CodecMethod::Pca);
  EXPECT_EQ(stats.method, CodecMethod::Pca);
  EXPECT_EQ(stats.pcaComponents, 3);
  EXPECT_GT(stats.rmseTrain, 0);
  EXPECT_GT(stats.rmseHoldout, 0);
  EXPECT_EQ(stats.holdoutImages, 8);
  nlohmann::json j = nlohmann::json::parse(compressStatsJson(stats));
  EXPECT_EQ(j["method"], "pca");
  EXPECT_EQ(j["pca_components"], 3);
  for (const char* key : {"rmse_train", "rmse_holdout", "ratio", "bytes", "seconds"}) EXPECT_TRUE(j.contains(key)) << key;
  for (const char* key : {"pca_mean", "pca_basis", "pca_coefficients", "total", "raw_float32", "file"})
    EXPECT_TRUE(j["bytes"].contains(key)) << key;
  EXPECT_FALSE(j["bytes"].contains("decoder"));
  EXPECT_EQ(j["bytes"]["pca_basis"].get<std::uint64_t>(), 81u * 3 * 3 * 4);
  EXPECT_EQ(j["bytes"]["pca_coefficients"].get<std::uint64_t>(), 64u * 3 * 4);
  EXPECT_EQ(j["bytes"]["total"].get<std::uint64_t>(), stats.sizes.total);
  EXPECT_DOUBLE_EQ(j["ratio"].get<double>(), stats.sizes.ratio);
  EXPECT_GT(j["seconds"]["pca"].get<double>(), 0);
  EXPECT_FALSE(j["seconds"].contains("cluster_parts"));  // no k-means here
  EXPECT_FALSE(j["seconds"].contains("train_parts"));    // nor training
  EXPECT_EQ(j["kmeans_iterations"].get<int>(), 0);
  EXPECT_DOUBLE_EQ(j["rmse_train"].get<double>(), stats.rmseTrain);
  // mean + coefficients x basis, computed here independently, gives the RMSE the compressor
  // reports (pooled over fitted and held-out images).
  double sse = 0;
  for (int i = 0; i < 81; ++i)
    for (int t = 0; t < 64; ++t)
      for (int c = 0; c < 3; ++c) sse += std::pow(testing::pcaValue(b, t, i, c) - m.stack.sample(i, t, c) / b.alpha, 2);
  double all = std::sqrt((stats.rmseTrain * stats.rmseTrain * 73 + stats.rmseHoldout * stats.rmseHoldout * 8) / 81);
  EXPECT_NEAR(std::sqrt(sse / (81 * 64 * 3)), all, 1e-5);
  std::string summary = formatCompressSummary(stats);
  for (const char* part : {"(pca, C = 3 components)", "fitted images", "held-out images", "coefficients",
                           "3 components explain", "pca (fit, coefficients, RMSE)"})
    EXPECT_TRUE(contains(summary, part)) << part << "\n" << summary;
  EXPECT_FALSE(contains(summary, "epochs")) << summary;
}

TEST(Compressor, UnwritableOutputFailsBeforeLoading) {
  // The input does not exist either: the error about the output proves it came first.
  try {
    compressBtf("/nonexistent/stack", "/nonexistent_dir/out.nbtf", quickOptions(4));
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_TRUE(contains(e.what(), "/nonexistent_dir/out.nbtf: output folder")) << e.what();
  }
}

TEST(Compressor, InterruptedRunLeavesNoOutputAndResumesToTheSameFile) {
  fs::path dir = fs::temp_directory_path() / ("nbtf_compressor_resume_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  std::string stack = testing::writeTestStack((dir / "stack").string());
  CompressOptions o = quickOptions(5);
  o.train.epochs = 40;
  std::string full = (dir / "full.nbtf").string(), part = (dir / "part.nbtf").string();
  o.saveEncoderPath = (dir / "with_encoder.nbtf").string();
  CompressStats whole = compressBtf(stack, full, o);
  ASSERT_FALSE(whole.interrupted);
  EXPECT_EQ(whole.sizes.fileBytes, fs::file_size(full));
  EXPECT_GT(whole.seconds.load, 0);
  // --save-encoder: the same material plus the encoder; the main output has none.
  CompressedBtf main = readNbtf(full), withEncoder = readNbtf(o.saveEncoderPath);
  EXPECT_TRUE(main.encoderState.empty());
  EXPECT_FALSE(withEncoder.encoderState.empty());
  withEncoder.encoderState.clear();
  EXPECT_EQ(serializeNbtf(withEncoder), readFileBytes(full));
  o.saveEncoderPath.clear();

  o.train.stopAtStep = 7;  // what SIGINT does, at a reproducible step
  CompressStats stopped = compressBtf(stack, part, o);
  EXPECT_TRUE(stopped.interrupted);
  EXPECT_FALSE(fs::exists(part));
  EXPECT_EQ(stopped.checkpointPath, part + ".ckpt");
  EXPECT_TRUE(fs::exists(part + ".ckpt"));

  o.train.stopAtStep = 0;
  o.train.resume = true;
  CompressStats resumed = compressBtf(stack, part, o);
  ASSERT_FALSE(resumed.interrupted);
  EXPECT_EQ(readFileBytes(part), readFileBytes(full));
  EXPECT_FALSE(fs::exists(part + ".ckpt"));  // a finished run removes its checkpoint
  fs::remove_all(dir);
}

TEST(Compressor, BuiltInDefaultsEqualConfigsDefaultJson) {
  // `nbtf compress` without --config uses TrainConfig{}: it must be configs/default.json.
  TrainConfig file = loadTrainConfig(std::string(NBTF_SOURCE_DIR) + "/configs/default.json");
  TrainConfig builtIn;
  EXPECT_EQ(trainConfigJson(file), trainConfigJson(builtIn));
  EXPECT_EQ(file.checkpointSeconds, builtIn.checkpointSeconds);
  // And the compress-only objects: the clustering space and the default k.
  const CompressConfig defaultJson = loadCompressConfig(std::string(NBTF_SOURCE_DIR) + "/configs/default.json");
  EXPECT_EQ(defaultJson.clusteringSpace, CompressOptions{}.clusteringSpace);
  EXPECT_EQ(defaultJson.clusters, CompressOptions{}.clusters);
  EXPECT_EQ(defaultJson.clusters, CompressConfig{}.clusters);
  // The default's k trains no more steps than k = 500 did (12,000 on a full 100 x 100 stack).
  EXPECT_EQ(planTraining(builtIn, defaultJson.clusters, 5905).totalSteps, 12000);
  EXPECT_EQ(planTraining(builtIn, 500, 5905).totalSteps, 12000);
  EXPECT_EQ(planTraining(builtIn, 250, 5905).totalSteps, 6000);
  // Every shipped config says its space: the paper's the paper's, the others the default.
  for (const std::string& name : builtInConfigNames())
    EXPECT_EQ(loadCompressConfig(name).clusteringSpace,
              name.rfind("paper", 0) == 0 ? ClusteringSpace::Log : ClusteringSpace::Linear)
        << name;
}

}  // namespace
}  // namespace nbtf
