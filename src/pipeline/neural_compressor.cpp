#include "pipeline/neural_compressor.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>

#include "cluster/clustering.h"
#include "codec/decoder.h"
#include "io/source_fingerprint.h"
#include "model/training_set.h"
#include "pipeline/adaptive.h"
#include "pipeline/compress_parts.h"
#include "preprocess/abrdf_matrix.h"
#include "preprocess/abrdf_source.h"
#include "util/error.h"
#include "util/parallel.h"
#include "util/timer.h"

namespace nbtf {

using json = nlohmann::json;

namespace {
// Rejects k larger than the texel count, as early as the texel count is known.
void checkClusterCount(int clusters, std::int64_t texels, const std::string& what) {
  if (clusters < 0) throw Error("--clusters must be >= 0 (0 = per-texel), got " + std::to_string(clusters));
  if (clusters > texels)
    throw Error("--clusters " + std::to_string(clusters) + " is larger than the " + std::to_string(texels) +
                " texels of " + what + " (k must be at most the texel count; 0 = per-texel)");
}


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

namespace detail {

void resolveDefaultClusters(CompressOptions& o, std::int64_t texels, CompressStats& stats) {
  if (!o.clustersAreDefault || o.pcaBaseline) return;
  const bool fromSize = o.texelsPerCluster > 0;  // the config's texels_per_cluster, not a capped k
  const int k = fromSize ? static_cast<int>(std::max<long long>(1, std::llround(double(texels) / o.texelsPerCluster)))
                         : defaultClusterCount(o.clusters, texels);
  if (fromSize) stats.texelsPerCluster = o.texelsPerCluster;
  else if (k != o.clusters) stats.clustersConfigured = o.clusters;
  o.clusters = k;
  o.clustersAreDefault = false;
}

void checkClusterCounts(const CompressOptions& o, std::int64_t texels, const std::string& what) {
  checkClusterCount(o.clusters, texels, what);
  if (o.adaptive.enabled && o.adaptive.maxClusters > texels)
    throw Error("--max-clusters " + std::to_string(o.adaptive.maxClusters) + " is larger than the " +
                std::to_string(texels) + " texels of " + what + " (at most the texel count)");
}

namespace {

// The standardization (eq. 1-4) and alpha (eq. 5). Clustered: the statistics only, from the
// stack; the standardized ABRDF matrix is streamed from the stack in slices
// (preprocess/abrdf_source.h) and never exists whole. Per-texel: the matrix itself, the
// encoder's input.
struct Standardized {
  float alpha = 0;
  MatrixXfCol matrix;                        // per-texel
  std::unique_ptr<StackAbrdfSource> source;  // clustered
};

Standardized standardize(const BtfStack& stack, const CompressOptions& o) {
  Standardized s;
  if (o.clusters > 0) {
    ColumnMoments moments;  // spare PCA a pass over the stack
    Standardization standardization = fitStandardization(stack, o.progress, &s.alpha, &moments);
    s.source = std::make_unique<StackAbrdfSource>(stack, std::move(standardization), std::move(moments));
  } else {
    s.alpha = targetAlpha(stack);
    s.matrix = abrdfMatrix(stack, o.progress);
    standardizeInPlace(s.matrix);
  }
  return s;
}

// PCA + k-means++ + per-cluster medians over the streamed matrix; `pcaComponents` receives the
// count used (the default is capped by the data).
ClusteringResult clusterTexels(const BtfStack& stack, const CompressOptions& o, const Standardized& data,
                               int& pcaComponents, CompressStats& stats) {
  ClusteringOptions co;
  co.clusters = o.clusters;
  const int maxComponents = static_cast<int>(std::min<Eigen::Index>(data.source->rows(), data.source->cols()));
  if (o.pcaComponents > maxComponents)
    throw Error("--components " + std::to_string(o.pcaComponents) + " exceeds the " + std::to_string(maxComponents) +
                " the data allows (min of texels and 3 x images)");
  pcaComponents = o.pcaComponents > 0 ? o.pcaComponents : std::min(kDefaultPcaComponents, maxComponents);
  co.pca.components = pcaComponents;
  co.pca.seed = o.train.seed;
  if (o.kmeansIterations > 0) co.kmeans.maxIterations = o.kmeansIterations;
  co.kmeans.seed = o.train.seed;
  co.seed = o.train.seed;
  co.progress = o.progress;
  if (o.adaptive.enabled) {
    co.clusters = initialAdaptiveClusters(o, stack.numTexels());
    co.keepScores = true;  // splits are 2-means in the same PCA space
  }
  // The linear space: the same texels as linear values / alpha, for PCA and k-means only.
  const auto space = clusteringSpaceSource(stack, o.clusteringSpace, data.alpha);
  stats.clusteringSpace = clusteringSpaceName(o.clusteringSpace);
  ClusteringResult clustering = clusterAbrdfs(*data.source, co, space.get());
  stats.pcaExplainedVarianceRatio = clustering.explainedVarianceRatio;
  stats.pcaComponents = pcaComponents;
  return clustering;
}

// The recipe training runs: the options' with the run's terms, controls and checkpoint.
TrainConfig trainingConfig(const BtfStack& stack, const CompressOptions& o, bool modulated, const TrainInputs& inputs,
                           int pcaComponents, CompressStats& stats) {
  TrainConfig config = o.train;
  config.model.outputTerms = modulated ? o.train.modulation.terms : 1;
  config.progress = config.progress && o.progress;
  config.stopFlag = o.stopFlag;
  config.checkpointPath = o.checkpointPath.empty() ? config.checkpointPath : o.checkpointPath;
  config.finalEvaluation = !assemblyMeasures(config, o.clusters);  // its figures would be replaced
  stats.checkpointPath = config.checkpointPath;
  if (config.distributed.enabled())
    config.distributed.mustAgree = distributedSettings(stack, stats.output, o, config, inputs.ids, pcaComponents);
  return config;
}

void recordTraining(const TrainResult& train, const TrainConfig& config, CompressStats& stats) {
  stats.seconds.trainParts = train.profile;
  stats.epochs = train.epochsRun;
  stats.steps = train.steps;
  stats.samplesPerSecond = train.samplesPerSecond;
  stats.decoderGflops = train.decoderGflops;
  stats.products = train.products;
  stats.worldSize = config.distributed.worldSize;
  stats.allReduceBytesPerStep = train.allReduceBytesPerStep;
  stats.allReduceSecondsPerStep = train.allReduceSecondsPerStep;
}

void recordClustering(const ClusteringResult& clustering, CompressStats& stats) {
  stats.seconds.clusterParts.pca = clustering.pcaSeconds;
  stats.seconds.clusterParts.kmeans = clustering.kmeansSeconds;
  stats.seconds.clusterParts.medians = clustering.representativeSeconds;
  stats.kmeansIterations = clustering.iterations;
}

std::vector<int> trainingImagesOf(const std::vector<std::uint8_t>& holdout) {
  std::vector<int> trainImages;
  for (int i = 0; i < static_cast<int>(holdout.size()); ++i)
    if (!holdout[i]) trainImages.push_back(i);
  return trainImages;
}

// Training fits the terms to exact per-cluster targets with these (orthonormal) coefficients;
// the stored ones are refit to the trained terms afterwards.
void addTrainingCoefficients(const BtfStack& stack, const CompressOptions& o, float alpha,
                             const std::vector<std::uint8_t>& holdout, TrainInputs& inputs, CompressStats& stats) {
  const ModulationConfig& mc = o.train.modulation;
  inputs.texelCoefficients = trainingCoefficients(stack, alpha, inputs.ids, o.clusters, holdout, mc, o.progress);
  inputs.coefficientTerms = mc.terms;
  inputs.coefficientChannels = mc.channels;
  stats.modulationTerms = mc.terms;
  stats.modulationChannels = mc.channels;
  stats.modulationBits = mc.bits;
}

// The compressed material (storage rounding, modulation refit, decoded RMSE) and its figures.
CompressedBtf assembleMaterial(const BtfStack& stack, const CompressOptions& o, const TrainConfig& config, float alpha,
                               TrainResult& train, TrainInputs& inputs, const ClusteringResult& clustering,
                               int pcaComponents, const std::vector<int>& trainImages,
                               const std::vector<std::uint8_t>& holdout, CompressStats& stats) {
  const auto t = Clock::now();
  CompressedBtf b = assembleCompressed(stack, config, stats.method, alpha, train, std::move(inputs.ids), o.clusters,
                                       inputs.texelCoefficients, trainImages, holdout, o.progress);
  stats.holdoutImages = static_cast<int>(b.holdoutImages.size());
  stats.rmseTrain = train.rmseTrain;
  stats.rmseHoldout = train.rmseHoldout;
  b.metadataJson = metadataJson(stack, config, train, o.clusters > 0 ? &clustering : nullptr, pcaComponents, stats, "");
  b.validate("compressed result");
  stats.sizes = computeSizes(b);
  stats.seconds.assemble = secondsSince(t);
  return b;
}

}  // namespace

CompressedBtf compressNeuralStack(const BtfStack& stack, const CompressOptions& options, CompressStats& stats) {
  CompressOptions o = options;
  resolveDefaultClusters(o, stack.numTexels(), stats);
  if (o.adaptive.enabled && o.clusters <= 0) throw Error("--adaptive needs the clustered mode (--clusters > 0)");
  stats.texels = stack.numTexels();
  stats.images = stack.numImages();
  stats.clusters = o.clusters;
  stats.method = compressMethod(o);
  checkClusterCounts(o, stack.numTexels(), stack.source.empty() ? "the material" : stack.source);

  auto t = Clock::now();
  Standardized data = standardize(stack, o);
  stats.alpha = data.alpha;
  stats.seconds.preprocess = secondsSince(t);

  // ---- Cluster, or per-texel: the standardized matrix itself
  TrainInputs inputs;
  inputs.stack = &stack;
  inputs.alpha = data.alpha;
  ClusteringResult clustering;
  int pcaComponents = 0;
  t = Clock::now();
  if (o.clusters > 0) {
    clustering = clusterTexels(stack, o, data, pcaComponents, stats);
    if (o.adaptive.enabled) {
      stats.seconds.cluster = secondsSince(t);
      return compressAdaptive(stack, o, *data.source, std::move(clustering), data.alpha, pcaComponents, stats);
    }
    data.source.reset();  // the encoder sees only the k representatives
    recordClustering(clustering, stats);
    inputs.encoderInputs = &clustering.representatives;
    inputs.ids = clustering.ids;
  } else {
    inputs.encoderInputs = &data.matrix;
  }

  // ---- Per-texel modulation (beyond the paper): factors from the training images, quantized
  // as the file stores them; training sees exactly what decoding will apply.
  const std::vector<std::uint8_t> holdout =
      holdoutImageMask(stack.numImages(), o.train.holdoutFraction, o.train.seed);
  const std::vector<int> trainImages = trainingImagesOf(holdout);
  const ModulationConfig& mc = o.train.modulation;
  const bool modulated = o.clusters > 0 && mc.mode != "none";
  stats.modulationMode = o.clusters > 0 ? mc.mode : "none";
  const auto tCoefficients = Clock::now();
  if (modulated) addTrainingCoefficients(stack, o, data.alpha, holdout, inputs, stats);
  stats.seconds.clusterParts.coefficients = secondsSince(tCoefficients);
  stats.seconds.cluster = secondsSince(t);
  if (stopRequested(o)) {
    stats.interrupted = true;
    return {};
  }

  // ---- Train
  const TrainConfig config = trainingConfig(stack, o, modulated, inputs, pcaComponents, stats);
  t = Clock::now();
  TrainResult train = trainModel(inputs, config);
  stats.seconds.train = secondsSince(t);
  recordTraining(train, config, stats);
  if (train.interrupted) {  // on a worker too: a stopped rank has not trained its shares
    stats.interrupted = true;
    return {};
  }
  if (train.worker) {  // rank > 0: its shares are trained; rank 0 assembles and writes the file
    stats.worker = true;
    return {};
  }
  if (o.clusters > 0) {
    stats.rmseFloor = modulated ? train.rmsePlainFloor : train.rmseFloor;  // from training's pass over the stack
    if (modulated) stats.rmseFloorModulated = train.rmseFloor;
  }

  return assembleMaterial(stack, o, config, data.alpha, train, inputs, clustering, pcaComponents, trainImages, holdout,
                          stats);
}

}  // namespace detail
}  // namespace nbtf
