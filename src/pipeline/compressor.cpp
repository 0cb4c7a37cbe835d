#include "pipeline/compressor.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <tuple>
#include <utility>
#include <nlohmann/json.hpp>

#include "cluster/cluster_values.h"
#include "cluster/clustering.h"
#include "codec/decoder.h"
#include "pipeline/adaptive.h"
#include "pipeline/compressor_internal.h"
#include "pipeline/memory_estimate.h"
#include "pipeline/pca_compressor.h"
#include "io/source_fingerprint.h"
#include "codec/texel_modulation.h"
#include "model/training_set.h"
#include "preprocess/abrdf_matrix.h"
#include "preprocess/abrdf_source.h"
#include "util/atomic_file.h"
#include "util/error.h"
#include "util/memory.h"
#include "util/parallel.h"
#include "util/timer.h"

namespace nbtf {
namespace {

using json = nlohmann::json;

constexpr int kDefaultPcaComponents = 32;


bool stopRequested(const CompressOptions& o) { return o.stopFlag && o.stopFlag->load(); }

json nullable(double v) { return v < 0 ? json(nullptr) : json(v); }

std::string checkpointPathFor(const std::string& output, const CompressOptions& o) {
  if (!o.checkpointPath.empty()) return o.checkpointPath;
  if (!o.train.checkpointPath.empty()) return o.train.checkpointPath;
  return defaultCheckpointPath(output);
}

// Rejects k larger than the texel count, as early as the texel count is known.
void checkClusterCount(int clusters, std::int64_t texels, const std::string& what) {
  if (clusters < 0) throw Error("--clusters must be >= 0 (0 = per-texel), got " + std::to_string(clusters));
  if (clusters > texels)
    throw Error("--clusters " + std::to_string(clusters) + " is larger than the " + std::to_string(texels) +
                " texels of " + what + " (k must be at most the texel count; 0 = per-texel)");
}

// An adaptive --size-budget below the decoder's own stored bytes cannot be met by any number
// of clusters: refused before loading (a budget above it but below the smallest file the run
// can write is found after the first stage).
void checkSizeBudgetAgainstTheDecoder(const CompressOptions& o) {
  if (!o.adaptive.enabled || o.adaptive.sizeBudget == 0) return;
  const std::string& storage = o.train.storage.decoder;
  const std::uint64_t bytesPerValue = storage == "int8" ? 1 : storage == "half" ? 2 : 4;
  std::uint64_t bytes = 0;
  for (const DenseLayer& layer : decoderShape(o.train.model).layers)
    bytes += bytesPerValue * (static_cast<std::uint64_t>(layer.in) * layer.out + layer.out);
  if (o.adaptive.sizeBudget < bytes)
    throw Error("--size-budget " + std::to_string(o.adaptive.sizeBudget) + " bytes is below the decoder alone (" +
                std::to_string(bytes) + " bytes as " + storage + ", before any cluster or texel data)");
}

// A default k becomes the input's (defaultClusterCount); the stats keep the configured one when
// the input capped it.
void resolveDefaultClusters(CompressOptions& o, std::int64_t texels, CompressStats& stats) {
  if (!o.clustersAreDefault || o.pcaBaseline) return;
  const int k = defaultClusterCount(o.clusters, texels);
  if (k != o.clusters) stats.clustersConfigured = o.clusters;
  o.clusters = k;
  o.clustersAreDefault = false;
}

// k and, with adaptive clusters, its cap: both at most the texel count.
void checkClusterCounts(const CompressOptions& o, std::int64_t texels, const std::string& what) {
  checkClusterCount(o.clusters, texels, what);
  if (o.adaptive.enabled && o.adaptive.maxClusters > texels)
    throw Error("--max-clusters " + std::to_string(o.adaptive.maxClusters) + " is larger than the " +
                std::to_string(texels) + " texels of " + what + " (at most the texel count)");
}

}  // namespace

namespace detail {

// Provenance stored in the file. Only what does not vary between identical runs: no
// timings, no output or checkpoint paths, so the same seed gives the same bytes.
std::string metadataJson(const BtfStack& stack, const TrainConfig& config,
                         const TrainResult& train, const ClusteringResult* clustering, int pcaComponents,
                         const CompressStats& stats, const std::string& adaptiveJson) {
  json meta;
  meta["config"] = json::parse(trainConfigJson(config));
  if (!config.builtInConfig.empty()) meta["config_name"] = config.builtInConfig;
  meta["seed"] = config.seed;
  meta["threads"] = config.threads > 0 ? config.threads : threadCount();
  meta["source"] = json::parse(sourceMetadataJson(stack));
  json t;
  t["rmse_train"] = train.rmseTrain;
  t["rmse_holdout"] = nullable(train.rmseHoldout);
  t["rmse_space"] = "linear RGB / alpha (eq. 10)";
  t["epochs"] = train.epochsRun;
  t["steps"] = train.steps;
  t["holdout_fraction"] = config.holdoutFraction;
  t["encoder_blocks"] = train.encoderBlocks;
  meta["training"] = t;
  if (clustering) {
    json c;
    c["k"] = stats.clusters;
    c["space"] = stats.clusteringSpace;  // absent in files before it was an option: "log"
    c["pca_components"] = pcaComponents;
    c["pca_explained_variance_ratio"] = clustering->explainedVarianceRatio;
    c["kmeans_iterations"] = clustering->iterations;
    c["kmeans_inertia"] = clustering->inertia;
    c["representative"] = "median";
    c["floor_rmse"] = nullable(stats.rmseFloor);
    if (stats.rmseFloorModulated >= 0) c["floor_rmse_modulated"] = stats.rmseFloorModulated;
    meta["clustering"] = c;
  }
  if (!adaptiveJson.empty()) meta["adaptive"] = json::parse(adaptiveJson);
  return meta.dump();
}

// RMSE (eq. 10, linear / alpha) of a compressed material against its stack, on the training
// and the held-out images, measured through the decoder: what the file will decode to.
// Per-image sums added in image order, so the result does not depend on the thread count.
std::pair<double, double> decodedRmse(const NbtfDecoder& decoder, const BtfStack& stack, float alpha,
                                      const std::vector<std::uint8_t>& holdout,
                                      const std::vector<const float*>& rowTerms) {
  const int images = stack.numImages(), views = stack.numViews();
  const std::size_t values = 3 * static_cast<std::size_t>(stack.numTexels());
  std::vector<double> sse(images, 0.0);
  const float invAlpha = 1.0f / alpha;
  parallelFor(images, [&](std::size_t begin, std::size_t end) {
    std::vector<float> decoded(values), reference(values);
    for (std::size_t i = begin; i < end; ++i) {
      if (i < rowTerms.size() && rowTerms[i])
        decoder.imageFromRowTerms(rowTerms[i], decoded.data(), OutputScale::Normalized);
      else
        decoder.decodeImage(stack.lights()[i / views], stack.views()[i % views], decoded.data(),
                            OutputScale::Normalized);
      stack.imageLinear(static_cast<int>(i), reference.data());
      double s = 0;
      for (std::size_t j = 0; j < values; ++j) {
        double d = static_cast<double>(decoded[j]) - static_cast<double>(reference[j] * invAlpha);
        s += d * d;
      }
      sse[i] = s;
    }
  });
  double sums[2] = {0, 0};
  int counts[2] = {0, 0};
  for (int i = 0; i < images; ++i) sums[holdout[i]] += sse[i], ++counts[holdout[i]];
  auto rmse = [&](int k) { return counts[k] ? std::sqrt(sums[k] / (static_cast<double>(counts[k]) * values)) : -1.0; };
  return {rmse(0), rmse(1)};
}

std::vector<float> trainingCoefficients(const BtfStack& stack, float alpha, const std::vector<std::int32_t>& ids,
                                        int clusters, const std::vector<std::uint8_t>& holdout,
                                        const ModulationConfig& mc, bool progress) {
  std::vector<std::uint8_t> useImage(holdout.size());
  for (std::size_t i = 0; i < holdout.size(); ++i) useImage[i] = !holdout[i];
  std::vector<float> coefficients =
      texelCoefficients(stack, alpha, ids, clusters, useImage, mc.terms, progress, mc.channels);
  return orthonormalizeTexelCoefficients(std::move(coefficients), mc.terms, ids, clusters, mc.channels);
}

namespace {

// How `storage` stores a material's parts; clusterPlanes: whether it has per-cluster planes.
PartStorage partStorage(const StorageConfig& storage, bool clusterPlanes) {
  PartStorage s;
  s.decoderHalf = storage.decoder == "half";
  s.decoderInt8 = storage.decoder == "int8";
  s.latentsHalf = storage.latents == "half";
  s.idsZstd = storage.ids == "zstd";
  s.metadataZstd = storage.metadata == "zstd";
  s.directionsZstd = storage.directions == "zstd";
  s.clusterPlanes8Bit = clusterPlanes && storage.clusterPlanes == "8bit";
  return s;
}

}  // namespace

bool assemblyMeasures(const TrainConfig& config, int clusters) {
  const bool modulated = clusters > 0 && config.modulation.mode != "none";
  return modulated || partStorage(config.storage, config.model.clusterPlaneFeatures > 0).anyRounding();
}

CompressedBtf assembleCompressed(const BtfStack& stack, const TrainConfig& config, CodecMethod method, float alpha,
                                 TrainResult& train, std::vector<std::int32_t> ids, int clusters,
                                 const std::vector<float>& texelCoefficients, const std::vector<int>& trainImages,
                                 const std::vector<std::uint8_t>& holdout, bool progress) {
  const ModulationConfig& mc = config.modulation;
  const bool modulated = clusters > 0 && mc.mode != "none";
  CompressedBtf b = compressedFrame(stack, method, alpha);
  b.decoder = std::move(train.decoder);
  b.planes = std::move(train.planes);
  b.clusterPlanes = std::move(train.clusterPlanes);
  b.directionEncoding = config.model.directionInputs;
  b.latentDim = config.model.latentDim;
  b.latentRows = train.latentRows;
  b.latents = std::move(train.latents);
  if (clusters > 0) b.ids = std::move(ids);
  b.holdoutImages = train.holdoutImages;
  std::sort(b.holdoutImages.begin(), b.holdoutImages.end());
  b.holdoutImages.erase(std::unique(b.holdoutImages.begin(), b.holdoutImages.end()), b.holdoutImages.end());
  b.encoderState = std::move(train.encoderState);
  b.storage = partStorage(config.storage, !b.clusterPlanes.empty());
  roundToStorage(b);
  std::vector<float> terms;  // modulated: image by image (trainImages), every cluster's terms
  std::vector<const float*> rowTerms;  // per image of the stack: its terms in `terms`, or null
  if (modulated) {
    // Refit: each texel's coefficients that best mix its cluster's trained (and rounded)
    // terms over the training images, then quantized as stored.
    b.modulation = quantizeTexelCoefficients(texelCoefficients, mc.terms, mc.bits, mc.channels);  // any valid codes
    NbtfDecoder decoder(b, DecoderOptions{}, "compressed result");
    const std::size_t k = static_cast<std::size_t>(clusters), n = trainImages.size(), outs = 3 * mc.terms;
    terms.resize(k * n * outs);
    rowTerms.assign(stack.numImages(), nullptr);
    for (std::size_t i = 0; i < n; ++i) rowTerms[trainImages[i]] = &terms[i * k * outs];
    const int views = stack.numViews();
    parallelFor(n, [&](std::size_t begin, std::size_t end) {
      for (std::size_t i = begin; i < end; ++i) {
        const int image = trainImages[i];
        decoder.decodeRowTerms(stack.lights()[image / views], stack.views()[image % views], &terms[i * k * outs]);
      }
    });
    std::vector<float> fitted =
        fitTexelCoefficients(stack, alpha, b.ids, clusters, trainImages, terms, mc.terms, progress, mc.meanWeight,
                             mc.channels);
    b.modulation = quantizeTexelCoefficients(
        fitted, mc.terms, mc.bits, mc.channels,
        mc.codes == "decorrelated" && mc.channels == 3 ? ModulationCodes::Decorrelated : ModulationCodes::Linear);
  }
  if (b.storage.anyRounding() || modulated || train.rmseTrain < 0) {
    // The rounded parts are what the file decodes to: measure those, not the trained floats.
    NbtfDecoder decoder(b, DecoderOptions{}, "compressed result");
    std::tie(train.rmseTrain, train.rmseHoldout) = decodedRmse(decoder, stack, alpha, holdout, rowTerms);
  }
  return b;
}

}  // namespace detail

std::string defaultCheckpointPath(const std::string& output) { return output + ".ckpt"; }

CompressedBtf compressedFrame(const BtfStack& stack, CodecMethod method, float alpha) {
  CompressedBtf b;
  b.method = method;
  b.width = stack.width();
  b.height = stack.height();
  b.crop = stack.crop;
  // In-memory stacks (tests, benchmarks) may not say where they came from.
  b.sourceWidth = stack.sourceWidth > 0 ? stack.sourceWidth : stack.width();
  b.sourceHeight = stack.sourceHeight > 0 ? stack.sourceHeight : stack.height();
  b.layout = stack.layout;
  b.sourceSampleType = stack.sampleType();
  b.lights = stack.lights();
  b.views = stack.views();
  b.alpha = alpha;
  return b;
}

std::string sourceMetadataJson(const BtfStack& stack) {
  json source;
  source["path"] = stack.source;
  source["layout"] = layoutName(stack.layout);
  source["sample_type"] = sampleTypeName(stack.sampleType());
  source["crop"] = stack.crop.empty() ? json(nullptr)
                                      : json::array({stack.crop.x, stack.crop.y, stack.crop.width, stack.crop.height});
  // What `nbtf eval` checks its reference against (io/source_fingerprint.h).
  source["fingerprint"] = json::parse(sourceFingerprintJson(sourceFingerprint(stack)));
  return source.dump();
}

namespace {

std::string hex64(std::uint64_t h) {
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(h));
  return text;
}
std::uint64_t fnv1a(const void* data, std::size_t n, std::uint64_t h = 0xcbf29ce484222325ull) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 0x100000001b3ull;
  return h;
}

void flattenJson(const json& j, const std::string& path, std::vector<std::pair<std::string, std::string>>& out) {
  if (j.is_object()) {
    for (auto it = j.begin(); it != j.end(); ++it) flattenJson(*it, path.empty() ? it.key() : path + "." + it.key(), out);
    return;
  }
  out.push_back({path, j.dump()});
}

// What every rank of a data-parallel run must share (DistributedConfig::mustAgree), named as
// the user knows it, the options first: ranks started with different commands get the option
// named, not a checksum.
std::vector<std::pair<std::string, std::string>> distributedSettings(const BtfStack& stack, const std::string& output,
                                                                     const CompressOptions& o,
                                                                     const TrainConfig& config,
                                                                     const std::vector<std::int32_t>& ids,
                                                                     int pcaComponents) {
  std::vector<std::pair<std::string, std::string>> s;
  s.push_back({"nbtf version", NBTF_VERSION});
  // Rank 0 writes the file: a rank told to write elsewhere would believe its path written.
  s.push_back({"-o", output});
  s.push_back({"--clusters", std::to_string(o.clusters)});
  s.push_back({"--seed", std::to_string(config.seed)});
  s.push_back({"--epochs", std::to_string(config.epochs)});
  s.push_back({"--holdout", json(config.holdoutFraction).dump()});
  s.push_back({"--components", std::to_string(pcaComponents)});
  s.push_back({"--crop", o.load.crop.empty() ? "none"
                                             : std::to_string(o.load.crop.x) + "," + std::to_string(o.load.crop.y) +
                                                   "," + std::to_string(o.load.crop.width) + "," +
                                                   std::to_string(o.load.crop.height)});
  s.push_back({"--layout", layoutName(stack.layout)});
  s.push_back({"source size (width x height, lights x views)",
               std::to_string(stack.width()) + "x" + std::to_string(stack.height()) + ", " +
                   std::to_string(stack.lights().size()) + "x" + std::to_string(stack.views().size())});
  // "auto" resolves by CPU: every rank must run the same products.
  s.push_back({"decoder products (training.products as this CPU runs it)", resolvedProducts(config)});
  const std::string fingerprint = sourceFingerprintJson(sourceFingerprint(stack));
  s.push_back({"source data (fingerprint of the images)", hex64(fnv1a(fingerprint.data(), fingerprint.size()))});
  // The recipe, key by key; threads may differ (the summed gradients do not depend on them).
  std::vector<std::pair<std::string, std::string>> recipe;
  flattenJson(json::parse(trainConfigJson(config)), "", recipe);
  for (auto& [key, value] : recipe)
    if (key != "training.seed" && key != "training.epochs" && key != "training.holdout_fraction" &&
        key != "training.threads")
      s.push_back({key + " (--config)", value});
  s.push_back({"training.backend (--config)", config.backend});
  // Clustering is deterministic for the settings above and the thread count; should it still
  // differ (another --threads, another CPU), the ranks would train on different clusters.
  s.push_back({"the texels' clusters (checksum; same --threads on every rank?)",
               ids.empty() ? "per-texel" : hex64(fnv1a(ids.data(), ids.size() * sizeof ids[0]))});
  return s;
}

}  // namespace

int defaultClusterCount(int configured, std::int64_t texels) {
  if (configured <= 0) return configured;
  return static_cast<int>(std::min<std::int64_t>(configured, std::max<std::int64_t>(1, texels / kTexelsPerDefaultCluster)));
}

CompressedBtf compressStack(const BtfStack& stack, const CompressOptions& options, CompressStats& stats) {
  if (options.pcaBaseline) return compressPcaStack(stack, options, stats);
  CompressOptions o = options;
  resolveDefaultClusters(o, stack.numTexels(), stats);
  if (o.adaptive.enabled && o.clusters <= 0) throw Error("--adaptive needs the clustered mode (--clusters > 0)");
  const int texels = stack.numTexels();
  stats.texels = texels;
  stats.images = stack.numImages();
  stats.clusters = o.clusters;
  stats.method = o.clusters > 0 ? CodecMethod::ClusteredNeural : CodecMethod::PerTexelNeural;
  checkClusterCounts(o, texels, stack.source.empty() ? "the material" : stack.source);

  // ---- Preprocess: log + standardize (eq. 1-4), alpha (eq. 5). Clustered: the statistics
  // only, from the stack; the standardized ABRDF matrix is streamed from the stack in slices
  // (preprocess/abrdf_source.h) and never exists whole. Per-texel: the matrix itself, the
  // encoder's input.
  auto t = Clock::now();
  float alpha = 0;
  MatrixXfCol x;
  std::unique_ptr<StackAbrdfSource> source;
  if (o.clusters > 0) {
    ColumnMoments moments;  // spare PCA a pass over the stack
    Standardization standardization = fitStandardization(stack, o.progress, &alpha, &moments);
    source = std::make_unique<StackAbrdfSource>(stack, std::move(standardization), std::move(moments));
  } else {
    alpha = targetAlpha(stack);
    x = abrdfMatrix(stack, o.progress);
    standardizeInPlace(x);
  }
  stats.alpha = alpha;
  stats.seconds.preprocess = secondsSince(t);

  // ---- Cluster (PCA + k-means++ + per-cluster medians), or per-texel: X itself
  TrainInputs inputs;
  inputs.stack = &stack;
  inputs.alpha = alpha;
  ClusteringResult clustering;
  int pcaComponents = 0;
  t = Clock::now();
  if (o.clusters > 0) {
    ClusteringOptions co;
    co.clusters = o.clusters;
    int maxComponents = static_cast<int>(std::min<Eigen::Index>(source->rows(), source->cols()));
    if (o.pcaComponents > maxComponents)
      throw Error("--components " + std::to_string(o.pcaComponents) + " exceeds the " +
                  std::to_string(maxComponents) + " the data allows (min of texels and 3 x images)");
    pcaComponents = o.pcaComponents > 0 ? o.pcaComponents : std::min(kDefaultPcaComponents, maxComponents);
    co.pca.components = pcaComponents;
    co.pca.seed = o.train.seed;
    if (o.kmeansIterations > 0) co.kmeans.maxIterations = o.kmeansIterations;
    co.kmeans.seed = o.train.seed;
    co.seed = o.train.seed;
    co.progress = o.progress;
    const bool adaptive = o.adaptive.enabled;
    if (adaptive) {
      co.clusters = detail::initialAdaptiveClusters(o, texels);
      co.keepScores = true;  // splits are 2-means in the same PCA space
    }
    // The linear space: the same texels as linear values / alpha, for PCA and k-means only.
    const auto space = clusteringSpaceSource(stack, o.clusteringSpace, alpha);
    stats.clusteringSpace = clusteringSpaceName(o.clusteringSpace);
    clustering = clusterAbrdfs(*source, co, space.get());
    if (adaptive) {
      stats.pcaExplainedVarianceRatio = clustering.explainedVarianceRatio;
      stats.pcaComponents = pcaComponents;
      stats.seconds.cluster = secondsSince(t);
      return detail::compressAdaptive(stack, o, *source, std::move(clustering), alpha, pcaComponents, stats);
    }
    source.reset();  // the encoder sees only the k representatives
    stats.seconds.clusterParts.pca = clustering.pcaSeconds;
    stats.seconds.clusterParts.kmeans = clustering.kmeansSeconds;
    stats.seconds.clusterParts.medians = clustering.representativeSeconds;
    stats.kmeansIterations = clustering.iterations;
    stats.pcaExplainedVarianceRatio = clustering.explainedVarianceRatio;
    stats.pcaComponents = pcaComponents;  // the count used (the default is capped by the data)
    inputs.encoderInputs = &clustering.representatives;
    inputs.ids = clustering.ids;
  } else {
    inputs.encoderInputs = &x;
  }

  // ---- Per-texel modulation (beyond the paper): factors from the training images, quantized
  // as the file stores them; training sees exactly what decoding will apply.
  const std::vector<std::uint8_t> holdout =
      holdoutImageMask(stack.numImages(), o.train.holdoutFraction, o.train.seed);
  std::vector<int> trainImages;
  for (int i = 0; i < stack.numImages(); ++i)
    if (!holdout[i]) trainImages.push_back(i);
  const ModulationConfig& mc = o.train.modulation;
  const bool modulated = o.clusters > 0 && mc.mode != "none";
  stats.modulationMode = o.clusters > 0 ? mc.mode : "none";
  const auto tCoefficients = Clock::now();
  if (modulated) {
    // Training fits the terms to exact per-cluster targets with these (orthonormal) coefficients;
    // the stored ones are refit to the trained terms afterwards.
    inputs.texelCoefficients =
        detail::trainingCoefficients(stack, alpha, inputs.ids, o.clusters, holdout, mc, o.progress);
    inputs.coefficientTerms = mc.terms;
    inputs.coefficientChannels = mc.channels;
    stats.modulationTerms = mc.terms;
    stats.modulationChannels = mc.channels;
    stats.modulationBits = mc.bits;
  }
  stats.seconds.clusterParts.coefficients = secondsSince(tCoefficients);
  stats.seconds.cluster = secondsSince(t);
  if (stopRequested(o)) {
    stats.interrupted = true;
    return {};
  }

  // ---- Train
  TrainConfig config = o.train;
  config.model.outputTerms = modulated ? mc.terms : 1;
  config.progress = config.progress && o.progress;
  config.stopFlag = o.stopFlag;
  config.checkpointPath = o.checkpointPath.empty() ? config.checkpointPath : o.checkpointPath;
  config.finalEvaluation = !detail::assemblyMeasures(config, o.clusters);  // its figures would be replaced
  stats.checkpointPath = config.checkpointPath;
  if (config.distributed.enabled())
    config.distributed.mustAgree = distributedSettings(stack, stats.output, o, config, inputs.ids, pcaComponents);
  t = Clock::now();
  TrainResult train = trainModel(inputs, config);
  stats.seconds.train = secondsSince(t);
  stats.seconds.trainParts = train.profile;
  stats.epochs = train.epochsRun;
  stats.steps = train.steps;
  stats.samplesPerSecond = train.samplesPerSecond;
  stats.decoderGflops = train.decoderGflops;
  stats.products = train.products;
  stats.worldSize = config.distributed.worldSize;
  stats.allReduceBytesPerStep = train.allReduceBytesPerStep;
  stats.allReduceSecondsPerStep = train.allReduceSecondsPerStep;
  if (train.interrupted) {  // on a worker too: a stopped rank has not trained its shares
    stats.interrupted = true;
    return {};
  }
  if (train.worker) {  // rank > 0: its shares are trained; rank 0 assembles and writes the file
    stats.worker = true;
    return {};
  }
  if (o.clusters > 0) {
    if (!modulated) {
      stats.rmseFloor = train.rmseFloor;
    } else {
      stats.rmseFloor = train.rmsePlainFloor;  // from training's pass over the stack
      stats.rmseFloorModulated = train.rmseFloor;
    }
  }

  // ---- Assemble the compressed material (storage rounding, modulation refit, decoded RMSE)
  t = Clock::now();
  CompressedBtf b = detail::assembleCompressed(stack, config, stats.method, alpha, train, std::move(inputs.ids),
                                               o.clusters, inputs.texelCoefficients, trainImages, holdout, o.progress);
  stats.holdoutImages = static_cast<int>(b.holdoutImages.size());
  stats.rmseTrain = train.rmseTrain;
  stats.rmseHoldout = train.rmseHoldout;
  b.metadataJson = detail::metadataJson(stack, config, train, o.clusters > 0 ? &clustering : nullptr,
                                        pcaComponents, stats, "");
  b.validate("compressed result");
  stats.sizes = computeSizes(b);
  stats.seconds.assemble = secondsSince(t);
  return b;
}

namespace {

// The neural methods estimate their standardization, PCA, clusters and per-texel code ranges
// over the texels: with a handful of them these are degenerate (one texel: every standardized
// value is 0, so the encoder sees nothing, and the run trains for minutes to a poor fit).
constexpr std::int64_t kMinNeuralTexels = 16;

void refuseTooFewTexels(const StackShape& shape, const std::string& input) {
  if (shape.texels() >= kMinNeuralTexels) return;
  throw fileError(input, std::to_string(shape.width) + " x " + std::to_string(shape.height) + " texels are too few for " +
                             "the neural methods (at least " + std::to_string(kMinNeuralTexels) +
                             ", e.g. 4 x 4): they estimate their standardization, PCA, clusters and per-texel code "
                             "ranges over the texels, which a handful of texels leaves degenerate; give a larger "
                             "--crop, or use --method pca");
}

std::string describeCheckpoint(const CheckpointSummary& c) {
  char buf[160];
  if (c.totalSteps > 0)
    std::snprintf(buf, sizeof buf, "step %lld of %lld, %.0f s of training%s", static_cast<long long>(c.step),
                  static_cast<long long>(c.totalSteps), c.elapsedSeconds,
                  c.step >= c.totalSteps ? ": its training had finished" : "");
  else
    std::snprintf(buf, sizeof buf, "step %lld, %.0f s of training", static_cast<long long>(c.step), c.elapsedSeconds);
  return buf;
}

// An interrupted run's checkpoint (and an adaptive run's stage state beside it) is the user's
// work: read now, before the stack is loaded, so a damaged one is refused at once; kept for
// --resume; deleted only with --restart; otherwise the run is refused, saying how far it got.
void refuseOrRestartCheckpoint(const CompressOptions& o) {
  const std::string& checkpoint = o.checkpointPath;
  const std::string state = adaptiveStatePath(checkpoint);
  std::error_code ec;
  const bool hasCheckpoint = std::filesystem::exists(checkpoint, ec), hasState = std::filesystem::exists(state, ec);
  if (!hasCheckpoint && !hasState) return;
  if (o.restart) {
    for (const std::string& path : {checkpoint, state}) {
      if (!std::filesystem::exists(path, ec)) continue;
      if (!std::filesystem::remove(path, ec) || ec)
        throw fileError(path, "--restart: cannot delete it: " + ec.message());
      std::fprintf(stderr, "nbtf compress: --restart: deleted %s\n", path.c_str());
    }
    return;
  }
  const std::string progress = hasCheckpoint ? describeCheckpoint(readCheckpointSummary(checkpoint)) : "";
  if (o.train.resume) return;
  if (hasCheckpoint)
    throw fileError(checkpoint, "an earlier run's training checkpoint (" + progress +
                                    ") is here and would be replaced; --resume continues that run, --restart "
                                    "deletes it and starts over");
  throw fileError(state, "an earlier adaptive run's stage state is here and would be replaced; --resume continues "
                         "that run, --restart deletes it and starts over");
}

}  // namespace

void refuseOverlappingCompressPaths(const std::string& input, const std::string& output, const CompressOptions& options,
                                    const std::string& configPath, const std::vector<PathUse>& extraOutputs) {
  std::vector<PathUse> inputs{{"<input>", input}, {"--config", configPath}};
  std::vector<PathUse> outputs{{"-o", output}, {"--save-encoder", options.saveEncoderPath}};
  if (!options.pcaBaseline) {
    const std::string checkpoint = checkpointPathFor(output, options);
    outputs.push_back({"the checkpoint", checkpoint});
    if (options.adaptive.enabled) outputs.push_back({"the adaptive state", adaptiveStatePath(checkpoint)});
  }
  outputs.insert(outputs.end(), extraOutputs.begin(), extraOutputs.end());
  refuseOverlappingPaths(inputs, outputs);
}

CompressStats compressBtf(const std::string& input, const std::string& output, const CompressOptions& options) {
  // ---- Fail before hours of work: no output may overwrite the input or another output, and
  // every output must be creatable now.
  refuseOverlappingCompressPaths(input, output, options);
  checkSizeBudgetAgainstTheDecoder(options);
  checkWritable(output);
  if (!options.saveEncoderPath.empty()) checkWritable(options.saveEncoderPath);
  CompressOptions o = options;
  if (o.pcaBaseline) {
    if (!o.saveEncoderPath.empty()) throw Error("--save-encoder: the PCA baseline has no encoder");
    if (o.pcaComponents < 1)
      throw Error("--method pca needs --components C >= 1 (the principal components kept), got " +
                  std::to_string(o.pcaComponents));
  } else {
    o.checkpointPath = checkpointPathFor(output, options);
    checkWritable(o.checkpointPath);
    refuseOrRestartCheckpoint(o);
  }
  CompressStats stats;
  stats.output = output;
  const bool cropped = !o.pcaBaseline && !o.load.crop.empty();
  if (cropped) checkCrop(input, o.load);  // a crop outside the images is that, not a cluster-count error

  {
    // ---- Fail before loading when the run cannot fit in --memory-limit.
    stats.memoryLimit = o.memoryLimit > 0 ? o.memoryLimit : defaultMemoryLimit();
    o.load.expandUpTo = expandBudget(stats.memoryLimit);
    const StackShape shape = stackShape(input, o.load);  // the crop's texels when cropped
    if (!o.pcaBaseline) refuseTooFewTexels(shape, input);
    resolveDefaultClusters(o, shape.texels(), stats);
    if (cropped) checkClusterCounts(o, shape.texels(), "the crop");
    const bool modulated = o.clusters > 0 && o.train.modulation.mode != "none";
    MemoryEstimate estimate = estimateCompressMemory(
        shape, o.clusters, o.pcaBaseline, o.pcaComponents > 0 ? o.pcaComponents : kDefaultPcaComponents,
        PcaOptions().oversampling, modulated ? o.train.modulation.terms * o.train.modulation.channels : 1, threadCount());
    const std::string outputDir = std::filesystem::path(output).parent_path().string();
    o.load.scratchDir = placeStackWithinLimit(o.stackStorage, outputDir, input, shape, estimate, stats.memoryLimit,
                                              o.memoryLimitText, o.progress);
    stats.stackScratchDir = o.load.scratchDir;
    stats.memoryEstimate = estimate.total();
  }
  auto t = Clock::now();
  LoadOptions load = o.load;
  load.progress = load.progress && o.progress;
  BtfStack stack = loadBtfStack(input, load);
  stats.seconds.load = secondsSince(t);
  stats.computedStack = stack.isComputed();
  if (stopRequested(o)) {
    stats.interrupted = true;
    return stats;
  }

  CompressedBtf btf = compressStack(stack, o, stats);  // fills the other stages' seconds
  stats.peakMemory = peakResidentBytes();
  if (stats.interrupted || stats.worker) return stats;

  // ---- Write (atomic); the encoder copy is the same file plus the encoder section.
  t = Clock::now();
  std::vector<std::uint8_t> encoder = std::move(btf.encoderState);
  btf.encoderState.clear();
  stats.sizes.fileBytes = writeNbtf(output, btf);
  if (!o.saveEncoderPath.empty()) {
    if (encoder.empty()) throw Error("--save-encoder: the trainer returned no encoder state");
    btf.encoderState = std::move(encoder);
    writeNbtf(o.saveEncoderPath, btf);
  }
  stats.seconds.write = secondsSince(t);
  // A finished run's default checkpoint is stale: remove it (a configured one is kept).
  if (!o.pcaBaseline && o.checkpointPath == defaultCheckpointPath(output)) {
    std::error_code ec;
    std::filesystem::remove(o.checkpointPath, ec);
    std::filesystem::remove(adaptiveStatePath(o.checkpointPath), ec);
  }
  return stats;
}

// ---- Reporting

namespace {
std::string formatMemoryLine(const CompressStats& s) {
  if (s.peakMemory == 0) return "";
  std::string line = "memory: peak " + formatBytes(s.peakMemory) + " resident (estimated before loading: " +
                     formatBytes(s.memoryEstimate) + "; --memory-limit " + formatBytes(s.memoryLimit) + ")\n";
  if (!s.stackScratchDir.empty())
    line += "        the image stack was kept in a scratch file in " + s.stackScratchDir +
            " (the system's file cache holds its pages, not the process)\n";
  if (s.computedStack)
    line += "        the UBO2014 input stayed factorized (its half-float expansion is over half the limit): values "
            "computed from the factors when read\n";
  return line;
}

// The cluster stage's parts are timed for one fixed-k clustering (not PCA, per-texel or adaptive).
bool hasClusterParts(const CompressStats& s) { return s.clusters > 0 && s.adaptiveStages.empty(); }
bool hasTrainParts(const CompressStats& s) {
  return s.method != CodecMethod::Pca && s.adaptiveStages.empty() && s.steps > 0;
}
}  // namespace

std::string formatCompressSummary(const CompressStats& s) {
  std::string out;
  char line[256];
  std::string parameter = s.clusters > 0             ? ", k = " + std::to_string(s.clusters)
                          : s.method == CodecMethod::Pca ? ", C = " + std::to_string(s.pcaComponents) + " components"
                                                         : "";
  if (s.clustersConfigured > 0)
    parameter += ": the config's " + std::to_string(s.clustersConfigured) + " capped to one cluster per " +
                 std::to_string(kTexelsPerDefaultCluster) + " of the " + std::to_string(s.texels) + " texels";
  std::snprintf(line, sizeof line, "summary: %s (%s%s)\n", s.output.c_str(), codecMethodName(s.method).c_str(),
                parameter.c_str());
  out += line;
  out += formatSizeTable(s.sizes);
  std::snprintf(line, sizeof line,
                "error: RMSE of eq. (10) over texels x images x RGB, on linear RGB / alpha (alpha = %.6g)\n",
                s.alpha);
  out += line;
  int trainImages = s.images - s.holdoutImages;
  const bool pca = s.method == CodecMethod::Pca;
  std::snprintf(line, sizeof line, "  %-16s %.6f  (%d images)\n", pca ? "fitted images" : "training images",
                s.rmseTrain, trainImages);
  out += line;
  if (s.rmseHoldout >= 0)
    std::snprintf(line, sizeof line, "  %-16s %.6f  (%d images%s)\n", "held-out images", s.rmseHoldout, s.holdoutImages,
                  pca ? ", interpolated from the fitted ones" : "");
  else
    std::snprintf(line, sizeof line, "  %-16s none (use --holdout F to measure interpolation)\n", "held-out images");
  out += line;
  if (s.rmseFloor >= 0) {
    std::snprintf(line, sizeof line,
                  "  %-16s %.6f  (cluster-mean floor: the best any one-value-per-cluster model can do, training "
                  "images)\n",
                  "floor", s.rmseFloor);
    out += line;
  }
  if (s.rmseFloorModulated >= 0) {
    std::snprintf(line, sizeof line,
                  "  %-16s %.6f  (clusters x per-texel modulation, %s, %d term%s%s: the floor the terms were "
                  "trained for; stored: %d-bit%s refit coefficients)\n",
                  "modulated floor", s.rmseFloorModulated, s.modulationMode.c_str(), s.modulationTerms,
                  s.modulationTerms > 1 ? "s" : "", s.modulationChannels > 1 ? " per channel" : "",
                  s.sizes.modulationBits ? s.sizes.modulationBits : s.modulationBits,
                  s.sizes.modulationDecorrelated ? " decorrelated" : "");
    out += line;
  }
  if (s.rmseTrain >= 0 && s.rmseFloor > 0) {
    const double floor = s.rmseFloorModulated >= 0 ? s.rmseFloorModulated : s.rmseFloor;
    std::snprintf(line, sizeof line,
                  "  %-16s %.0f%% of the training MSE is the floor (clustering%s), %.0f%% the network\n", "split",
                  100 * std::min(1.0, floor * floor / (s.rmseTrain * s.rmseTrain)),
                  s.rmseFloorModulated >= 0 ? " + per-texel modulation" : "",
                  100 * std::max(0.0, 1 - floor * floor / (s.rmseTrain * s.rmseTrain)));
    out += line;
  }
  if (!s.adaptiveStages.empty()) {
    std::snprintf(line, sizeof line, "adaptive: %zu stages, k %d -> %d (%s)\n", s.adaptiveStages.size(),
                  s.adaptiveStages.front().clusters, s.clusters, s.adaptiveStopReason.c_str());
    out += line;
    out += "  stage      k      steps  rmse (train)        bytes  then: merges pruned splits\n";
    for (std::size_t i = 0; i < s.adaptiveStages.size(); ++i) {
      const AdaptiveStage& st = s.adaptiveStages[i];
      std::snprintf(line, sizeof line, "  %5zu %6d %10lld  %12.6f %12llu  %6d %6d %6d\n", i + 1, st.clusters,
                    static_cast<long long>(st.steps), st.rmseTrain, static_cast<unsigned long long>(st.bytes),
                    st.merges, st.pruned, st.splits);
      out += line;
    }
  }
  const StageSeconds& t = s.seconds;
  if (pca) {
    std::snprintf(line, sizeof line,
                  "pca: %d components explain %.2f%% of the variance of the fitted ABRDFs (linear RGB / alpha)\n",
                  s.pcaComponents, 100 * s.pcaExplainedVarianceRatio);
    out += line;
    std::snprintf(line, sizeof line,
                  "time (wall clock, s): load %.2f | preprocess %.2f | pca (fit, coefficients, RMSE) %.2f | write "
                  "%.2f | total %.2f\n",
                  t.load, t.preprocess, t.pca, t.write, t.total());
    out += line;
    out += formatMemoryLine(s);
    return out;
  }
  std::snprintf(line, sizeof line, "training: %d epochs, %lld steps, %.3g decoder samples/s, %.3g GFLOP/s (%s products)\n",
                s.epochs, static_cast<long long>(s.steps), s.samplesPerSecond, s.decoderGflops, s.products.c_str());
  out += line;
  if (s.worldSize > 1) {
    std::snprintf(line, sizeof line,
                  "data-parallel: %d processes (c10d Gloo); gradients all-reduced every step: %.1f KiB, %.2f ms per "
                  "step on this rank\n",
                  s.worldSize, s.allReduceBytesPerStep / 1024, 1e3 * s.allReduceSecondsPerStep);
    out += line;
  }
  std::snprintf(line, sizeof line,
                "time (wall clock, s): load %.2f | preprocess %.2f | cluster %.2f | train %.2f | assemble %.2f | "
                "write %.2f | total %.2f\n",
                t.load, t.preprocess, t.cluster, t.train, t.assemble, t.write, t.total());
  out += line;
  if (hasClusterParts(s)) {
    std::snprintf(line, sizeof line,
                  "  cluster: pca %.2f | k-means %.2f (%d rounds) | medians %.2f | modulation coefficients and floor "
                  "%.2f\n",
                  t.clusterParts.pca, t.clusterParts.kmeans, s.kmeansIterations, t.clusterParts.medians,
                  t.clusterParts.coefficients);
    out += line;
  }
  if (hasTrainParts(s)) {
    const auto& p = t.trainParts;
    std::snprintf(line, sizeof line,
                  "  train: decoder %.2f | encoder %.2f | sampling %.2f | optimizer %.2f | set-up and final "
                  "evaluation %.2f\n",
                  p.decoder, p.encoder, p.sampling, p.optimizer, std::max(0.0, t.train - p.steps()));
    out += line;
  }
  out += formatMemoryLine(s);
  return out;
}

std::string compressStatsJson(const CompressStats& s) {
  json j;
  j["output"] = s.output;
  j["method"] = codecMethodName(s.method);
  j["clusters"] = s.clusters;
  j["clusters_configured"] = s.clustersConfigured > 0 ? json(s.clustersConfigured) : json(nullptr);
  j["pca_components"] = s.pcaComponents;
  j["kmeans_iterations"] = s.kmeansIterations;
  j["clustering_space"] = s.clusteringSpace.empty() ? json(nullptr) : json(s.clusteringSpace);
  j["texels"] = s.texels;
  j["images"] = s.images;
  j["holdout_images"] = s.holdoutImages;
  j["alpha"] = s.alpha;
  j["rmse_train"] = nullable(s.rmseTrain);
  j["rmse_holdout"] = nullable(s.rmseHoldout);
  j["rmse_space"] = "linear RGB / alpha (eq. 10)";
  j["rmse_floor"] = nullable(s.rmseFloor);
  j["rmse_floor_modulated"] = nullable(s.rmseFloorModulated);
  j["modulation"] = {{"mode", s.modulationMode},
                     {"terms", s.modulationTerms},
                     {"channels", s.modulationChannels},
                     {"bits", s.modulationBits},
                     {"codes", s.sizes.modulationDecorrelated ? "decorrelated" : "linear"},
                     {"stored_bits", s.sizes.modulationBits}};
  j["ratio"] = s.sizes.ratio;
  if (s.method == CodecMethod::Pca)
    j["bytes"] = {{"pca_mean", s.sizes.pcaMean},
                  {"pca_basis", s.sizes.pcaBasis},
                  {"pca_coefficients", s.sizes.pcaCoefficients},
                  {"total", s.sizes.total},
                  {"raw_float32", s.sizes.rawFloat32},
                  {"file", s.sizes.fileBytes}};
  else
    j["bytes"] = {{"decoder", s.sizes.decoder}, {"latents", s.sizes.latents},       {"ids", s.sizes.ids},
                  {"per_texel", s.sizes.modulation},
                  {"total", s.sizes.total},     {"raw_float32", s.sizes.rawFloat32}, {"file", s.sizes.fileBytes}};
  if (s.sizes.planes) j["bytes"]["planes"] = s.sizes.planes;
  if (s.sizes.clusterPlanes) j["bytes"]["cluster_planes"] = s.sizes.clusterPlanes;
  j["seconds"] = {{"load", s.seconds.load},   {"preprocess", s.seconds.preprocess}, {"cluster", s.seconds.cluster},
                  {"train", s.seconds.train}, {"pca", s.seconds.pca},               {"write", s.seconds.write},
                  {"assemble", s.seconds.assemble}, {"total", s.seconds.total()}};
  if (hasClusterParts(s))
    j["seconds"]["cluster_parts"] = {{"pca", s.seconds.clusterParts.pca},
                                     {"kmeans", s.seconds.clusterParts.kmeans},
                                     {"medians", s.seconds.clusterParts.medians},
                                     {"coefficients", s.seconds.clusterParts.coefficients}};
  if (hasTrainParts(s))
    j["seconds"]["train_parts"] = {{"sampling", s.seconds.trainParts.sampling},
                                   {"encoder", s.seconds.trainParts.encoder},
                                   {"decoder", s.seconds.trainParts.decoder},
                                   {"optimizer", s.seconds.trainParts.optimizer}};
  j["epochs"] = s.epochs;
  j["steps"] = s.steps;
  j["samples_per_second"] = s.samplesPerSecond;
  j["decoder_gflops"] = s.decoderGflops;
  j["products"] = s.products;
  j["pca_explained_variance_ratio"] = nullable(s.pcaExplainedVarianceRatio);
  j["interrupted"] = s.interrupted;
  j["memory_bytes"] = {{"peak_resident", s.peakMemory}, {"estimate", s.memoryEstimate}, {"limit", s.memoryLimit}};
  j["stack_scratch_dir"] = s.stackScratchDir;
  j["computed_stack"] = s.computedStack;
  j["world_size"] = s.worldSize;
  j["all_reduce_bytes_per_step"] = s.allReduceBytesPerStep;
  j["all_reduce_seconds_per_step"] = s.allReduceSecondsPerStep;
  if (s.adaptiveStages.empty()) {
    j["adaptive"] = nullptr;
  } else {
    json stages = json::array();
    for (const AdaptiveStage& st : s.adaptiveStages)
      stages.push_back({{"k", st.clusters}, {"steps", st.steps}, {"rmse_train", st.rmseTrain}, {"bytes", st.bytes},
                        {"splits", st.splits}, {"merges", st.merges}, {"pruned", st.pruned}});
    j["adaptive"] = {{"stages", stages}, {"stop_reason", s.adaptiveStopReason}};
  }
  return j.dump(2) + "\n";
}

}  // namespace nbtf
