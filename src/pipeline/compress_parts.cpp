#include "pipeline/compress_parts.h"

#include <cmath>

#include "cluster/cluster_values.h"
#include "codec/texel_modulation.h"
#include "io/source_fingerprint.h"
#include "model/training_set.h"
#include "util/error.h"
#include "util/parallel.h"
#include "util/progress.h"

namespace nbtf {

using json = nlohmann::json;

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
  t["rmse_holdout"] = jsonOrNull(train.rmseHoldout);
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
    c["floor_rmse"] = jsonOrNull(stats.rmseFloor);
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

}  // namespace nbtf
