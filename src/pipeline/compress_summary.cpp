// The compress run's final summary, as text and as JSON (compressor.h).
#include <cstdio>

#include "pipeline/compress_parts.h"
#include "pipeline/compressor.h"
#include "pipeline/size_budget.h"
#include "util/memory.h"
#include "util/printable.h"

namespace nbtf {

using json = nlohmann::json;

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

// "error: ...": the RMSE on training and held-out images, the floors and the split of the MSE.
std::string errorLines(const CompressStats& s) {
  std::string out;
  char line[256];
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
  return out;
}

// "adaptive: ...": one line per stage.
std::string adaptiveLines(const CompressStats& s) {
  std::string out;
  char line[256];
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
  return out;
}

// Training's figures and the time per stage (and its parts), then the memory line.
std::string timeLines(const CompressStats& s) {
  std::string out;
  char line[256];
  const StageSeconds& t = s.seconds;
  if (s.method == CodecMethod::Pca) {
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

}  // namespace

std::string formatCompressSummary(const CompressStats& s) {
  std::string out;
  char line[256];
  std::string parameter = s.clusters > 0             ? ", k = " + std::to_string(s.clusters)
                          : s.method == CodecMethod::Pca ? ", C = " + std::to_string(s.pcaComponents) + " components"
                                                         : "";
  if (s.texelsPerCluster > 0) {
    char per[96];
    std::snprintf(per, sizeof per, ": one cluster per %g of the %d texels (the config's texels_per_cluster)",
                  s.texelsPerCluster, s.texels);
    parameter += per;
  }
  if (s.clustersConfigured > 0)
    parameter += ": the config's " + std::to_string(s.clustersConfigured) + " capped to one cluster per " +
                 std::to_string(kTexelsPerDefaultCluster) + " of the " + std::to_string(s.texels) + " texels";
  if (s.sizeBudget > 0) {
    char per[96];
    std::snprintf(per, sizeof per, ": one cluster per %g texels, the densest point, smaller than --size-budget",
                  kDensestTexelsPerCluster);
    parameter += s.sizeBudgetAtDensest ? per : ": the most that fit --size-budget";
    if (!s.sizeBudgetConfig.empty())
      parameter += ", in " + s.sizeBudgetConfig + "'s recipe, the named config the budget reaches";
  }
  out += "summary: " + s.output + " (" + codecMethodName(s.method) + parameter + ")\n";
  out += formatSizeTable(s.sizes);
  if (s.sizeBudget > 0 && s.sizes.fileBytes > 0) {
    std::snprintf(line, sizeof line,
                  "  size budget  %s B: estimated before loading at most %s B, written %s B (%.0f%% of the budget)\n",
                  groupedDigits(s.sizeBudget).c_str(), groupedDigits(s.sizeBudgetEstimate).c_str(),
                  groupedDigits(s.sizes.fileBytes).c_str(), 100.0 * s.sizes.fileBytes / s.sizeBudget);
    out += line;
  }
  if (s.adaptiveStages.empty()) return out + errorLines(s) + timeLines(s);
  return out + errorLines(s) + adaptiveLines(s) + timeLines(s);
}

std::string compressStatsJson(const CompressStats& s) {
  json j;
  j["output"] = s.output;
  j["method"] = codecMethodName(s.method);
  j["clusters"] = s.clusters;
  j["clusters_configured"] = s.clustersConfigured > 0 ? json(s.clustersConfigured) : json(nullptr);
  j["texels_per_cluster"] = s.texelsPerCluster > 0 ? json(s.texelsPerCluster) : json(nullptr);
  j["size_budget"] = s.sizeBudget > 0 ? json({{"bytes", s.sizeBudget},
                                              {"estimate_bytes", s.sizeBudgetEstimate},
                                              {"config", s.sizeBudgetConfig.empty() ? json(nullptr) : json(s.sizeBudgetConfig)},
                                              {"at_densest", s.sizeBudgetAtDensest}})
                                      : json(nullptr);
  j["pca_components"] = s.pcaComponents;
  j["kmeans_iterations"] = s.kmeansIterations;
  j["clustering_space"] = s.clusteringSpace.empty() ? json(nullptr) : json(s.clusteringSpace);
  j["texels"] = s.texels;
  j["images"] = s.images;
  j["holdout_images"] = s.holdoutImages;
  j["alpha"] = s.alpha;
  j["rmse_train"] = detail::jsonOrNull(s.rmseTrain);
  j["rmse_holdout"] = detail::jsonOrNull(s.rmseHoldout);
  j["rmse_space"] = "linear RGB / alpha (eq. 10)";
  j["rmse_floor"] = detail::jsonOrNull(s.rmseFloor);
  j["rmse_floor_modulated"] = detail::jsonOrNull(s.rmseFloorModulated);
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
  j["pca_explained_variance_ratio"] = detail::jsonOrNull(s.pcaExplainedVarianceRatio);
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
