#include "pipeline/size_budget.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "codec/nbtf_file.h"
#include "codec/texel_modulation.h"
#include "model/training_set.h"
#include "pipeline/compress_parts.h"
#include "pipeline/neural_compressor.h"
#include "util/error.h"

namespace nbtf {
namespace {

// What the run adds to the metadata beside its config (statistics, the source's path and
// fingerprint, the clustering): about 1 KiB zstd-coded in the files written so far, allowed for
// four times over, with the few bytes a zstd frame of incompressible data adds to the ids and codes.
constexpr std::uint64_t kRunMetadataAllowance = 4096;

CompressedBtf frameOf(const BtfInput& in, CodecMethod method) {
  CompressedBtf b;
  b.method = method;
  b.width = in.shape.width;
  b.height = in.shape.height;
  b.crop = in.crop;
  b.sourceWidth = in.sourceWidth > 0 ? in.sourceWidth : in.shape.width;
  b.sourceHeight = in.sourceHeight > 0 ? in.sourceHeight : in.shape.height;
  b.layout = in.listing.layout;
  b.sourceSampleType = in.shape.type;
  b.lights = in.listing.lights;
  b.views = in.listing.views;
  b.alpha = 1;
  return b;
}

std::vector<int> holdoutImagesOf(const BtfInput& in, const TrainConfig& train) {
  const std::vector<std::uint8_t> mask = holdoutImageMask(in.shape.images(), train.holdoutFraction, train.seed);
  std::vector<int> images;
  for (int i = 0; i < static_cast<int>(mask.size()); ++i)
    if (mask[i]) images.push_back(i);
  return images;
}

// The clustered material's parts at their shapes: the decoder, planes, latents and cluster
// planes as the config sizes them, the ids and per-texel codes uniform at random.
void addClusteredParts(CompressedBtf& b, const TrainConfig& train, int k) {
  ModelConfig model = train.model;
  const ModulationConfig& mc = train.modulation;
  const bool modulated = mc.mode != "none";
  model.outputTerms = modulated ? mc.terms : 1;
  b.decoder = decoderShape(model);
  b.directionEncoding = model.directionInputs;
  if (model.planeFeatures > 0) {
    b.planes.resolution = model.planeResolution;
    b.planes.features = model.planeFeatures;
    b.planes.values.assign(b.planes.valueCount(), 0.0f);
  }
  if (model.clusterPlaneFeatures > 0) {
    b.clusterPlanes.resolution = model.clusterPlaneResolution;
    b.clusterPlanes.features = model.clusterPlaneFeatures;
    b.clusterPlanes.rows = k;
    b.clusterPlanes.values.assign(b.clusterPlanes.valueCount(), 0.0f);
  }
  b.latentDim = model.latentDim;
  b.latentRows = k;
  b.latents.assign(static_cast<std::size_t>(k) * model.latentDim, 0.0f);
  std::mt19937 random(1);
  const std::size_t texels = static_cast<std::size_t>(b.numTexels());
  b.ids.resize(texels);
  std::uniform_int_distribution<std::int32_t> id(0, k - 1);
  for (std::int32_t& i : b.ids) i = id(random);
  if (modulated) {
    const int columns = mc.terms * mc.channels;
    b.modulation = quantizeTexelCoefficients(std::vector<float>(texels * columns, 0.0f), mc.terms, mc.bits,
                                             mc.channels,
                                             mc.codes == "decorrelated" && mc.channels == 3 ? ModulationCodes::Decorrelated
                                                                                            : ModulationCodes::Linear);
    // Codes uniform over the configured width: the files measured store about 4.5 bits a code
    // zstd-coded (6-bit codes; decorrelated ones one bit wider but as peaked), the estimate 6.
    b.modulation.bits = mc.bits;
    std::uniform_int_distribution<int> code(0, (1 << mc.bits) - 1);
    for (std::uint16_t& c : b.modulation.codes) c = static_cast<std::uint16_t>(code(random));
  }
  b.storage = detail::partStorage(train.storage, !b.clusterPlanes.empty());
}

void addPcaParts(CompressedBtf& b, const TrainConfig& train, int components) {
  const std::size_t values = 3 * static_cast<std::size_t>(b.numImages());
  b.latentDim = components;
  b.latentRows = b.numTexels();
  b.latents.assign(static_cast<std::size_t>(b.latentRows) * components, 0.0f);
  b.pcaMean.assign(values, 0.0f);
  b.pcaBasis.assign(values * components, 0.0f);
  b.storage.metadataZstd = train.storage.metadata == "zstd";
  b.storage.directionsZstd = train.storage.directions == "zstd";
}

// The largest count in [1, most] whose file fits `budget` (0: not even 1). Bytes grow with the count.
int largestWithin(const BtfInput& in, const CompressOptions& o, std::uint64_t budget, int most) {
  if (estimatedFileBytes(in, o, 1) > budget) return 0;
  if (estimatedFileBytes(in, o, most) <= budget) return most;
  int fits = 1, over = most;
  while (over - fits > 1) {
    const int mid = fits + (over - fits) / 2;
    (estimatedFileBytes(in, o, mid) <= budget ? fits : over) = mid;
  }
  return fits;
}

// The k a recipe's own point has on this input (its clusters capped, or its texels_per_cluster).
int ownClusters(CompressOptions o, std::int64_t texels) {
  CompressStats ignored;
  detail::resolveDefaultClusters(o, texels, ignored);
  return o.clusters;
}

// The k at which the budget takes a curve's recipe over the plainer one before it.
int takeoverClusters(const CompressOptions& recipe, std::int64_t texels, int most) {
  return static_cast<int>(std::min<std::int64_t>(most, std::int64_t(recipe.sizeBudgetTakeover) * ownClusters(recipe, texels)));
}

std::string recipeName(const CompressOptions& o) {
  return o.train.builtInConfig.empty() ? "the config's recipe" : o.train.builtInConfig + "'s recipe";
}

}  // namespace

std::uint64_t estimatedFileBytes(const BtfInput& in, const CompressOptions& o, int count) {
  CompressedBtf b = frameOf(in, compressMethod(o));
  if (o.pcaBaseline)
    addPcaParts(b, o.train, count);
  else
    addClusteredParts(b, o.train, count);
  b.holdoutImages = holdoutImagesOf(in, o.train);
  b.metadataJson = trainConfigJson(o.train);
  return serializeNbtf(b).size() + kRunMetadataAllowance;
}

void chooseSizeBudgetPoint(const BtfInput& in, CompressOptions& o, CompressStats& stats) {
  const std::uint64_t budget = o.sizeBudget;
  if (budget == 0) return;
  const std::int64_t texels = in.shape.texels();
  const std::string budgetText = "--size-budget " + std::to_string(budget) + " bytes";
  if (o.pcaBaseline) {
    const int most = static_cast<int>(std::min<std::int64_t>(texels, 3LL * in.shape.images()));
    o.pcaComponents = largestWithin(in, o, budget, most);
    if (o.pcaComponents == 0)
      throw fileError(in.path, budgetText + " is below the smallest PCA file of this input (one component: " +
                                   std::to_string(estimatedFileBytes(in, o, 1)) + " bytes)");
  } else {
    if (ownClusters(o, texels) == 0)
      throw Error(budgetText + " chooses the number of clusters (or of PCA's components); the per-texel method has "
                               "one latent per texel and nothing to choose");
    const int most = static_cast<int>(std::max<std::int64_t>(1, std::llround(double(texels) / kDensestTexelsPerCluster)));
    // The curve's largest recipe whose takeover point fits. Not one below it: a richer recipe
    // with few clusters is behind a plainer one with many at the same size (docs/compress.md,
    // *A size budget*: balanced at k = 500 against the default at k = 4000).
    const std::vector<CompressOptions>& curve = o.sizeBudgetCurve;
    std::size_t chosen = 0;
    for (std::size_t i = 1; i < curve.size(); ++i)
      if (estimatedFileBytes(in, curve[i], takeoverClusters(curve[i], texels, most)) <= budget) chosen = i;
    if (!curve.empty()) {  // the recipe: what a config sets (the run's own options stay)
      const CompressOptions& recipe = curve[chosen];
      o.train = recipe.train;
      o.clusteringSpace = recipe.clusteringSpace;
      stats.sizeBudgetConfig = o.train.builtInConfig;
    }
    const int k = largestWithin(in, o, budget, most);
    if (k == 0)
      throw fileError(in.path, budgetText + " is below the smallest file of this input: " + recipeName(o) +
                                   " with one cluster is up to " + std::to_string(estimatedFileBytes(in, o, 1)) +
                                   " bytes");
    o.clusters = k;
    stats.sizeBudgetAtDensest = k == most && estimatedFileBytes(in, o, k) < budget;
    o.clustersAreDefault = false;
    o.texelsPerCluster = 0;
  }
  o.sizeBudgetCurve.clear();
  stats.sizeBudget = budget;
  stats.sizeBudgetEstimate = estimatedFileBytes(in, o, o.pcaBaseline ? o.pcaComponents : o.clusters);
}

}  // namespace nbtf
