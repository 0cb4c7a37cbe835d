// nbtf cluster <input> --clusters K -o DIR: the clustering stage alone (log + standardize, PCA,
// k-means++ in the --space chosen, representatives; pipeline/cluster_stack.h), writing
// DIR/labels.png (the id list, a colour per cluster), DIR/texel_colour.png and
// DIR/cluster_colour.png (each texel's mean colour over all images, and its cluster's: what the
// clustering keeps) and DIR/summary.json.
#include <cstdio>
#include <filesystem>
#include <memory>

#include "cli_common.h"
#include "commands.h"
#include "options/clustering_options.h"
#include "options/memory_options.h"
#include "pipeline/cluster_stack.h"
#include "util/memory.h"
#include "util/progress.h"

namespace nbtf::cli {
namespace {

// The summary lines: what was clustered, PCA, k-means, the cluster sizes, memory, the files.
void printSummary(const ClusterStackRun& done, const ClusterOutputFiles& files, const ClusterStackOptions& run) {
  const ClusteringOptions& options = run.clustering;
  const ClusteringSpace space = run.space;
  const ClusteringResult& result = done.result;
  const int texels = done.info.width * done.info.height;
  const auto& sizes = files.summaryJson["cluster_sizes"];
  std::printf("clustered %d texels (%d x %d, %d images) into %d clusters in %.2f s\n", texels, done.info.width,
              done.info.height, done.info.images, options.clusters, done.info.totalSeconds);
  const std::string sampled = result.pcaSampledTexels > 0
                                  ? ", subspace from " + std::to_string(result.pcaSampledTexels) + " sampled texels"
                                  : "";
  std::printf("  PCA          %d components: %.2f%% of the variance of the %s (%.2f s%s)\n", options.pca.components,
              100.0 * result.explainedVarianceRatio,
              space == ClusteringSpace::Linear ? "linear ABRDFs / alpha" : "standardized log ABRDFs", result.pcaSeconds,
              sampled.c_str());
  const std::string stop = !result.converged      ? ", iteration limit reached"
                          : result.lastMoved == 0 ? ", converged"
                                                  : ", settled (" + std::to_string(result.lastMoved) + " texels still moving)";
  std::printf("  k-means      inertia %.6g in PCA space (%.4g per texel), %d iterations%s (%.2f s)\n",
              result.inertia, result.inertia / texels, result.iterations, stop.c_str(), result.kmeansSeconds);
  std::printf("  sizes        min %d, median %d, max %d texels%s\n", sizes["min"].get<int>(), sizes["median"].get<int>(),
              sizes["max"].get<int>(),
              result.emptyClusters ? (", " + std::to_string(result.emptyClusters) + " empty (too few distinct ABRDFs)").c_str()
                                   : "");
  std::printf("  memory       peak %s resident (--memory-limit %s)\n", formatBytes(done.info.peakMemoryBytes).c_str(),
              formatBytes(done.memoryLimit).c_str());
  std::printf("  wrote        %s (ids), %s and %s (mean colour per texel / per cluster), %s\n", files.labels.c_str(),
              files.texelColour.c_str(), files.clusterColour.c_str(), files.summary.c_str());
}

int runCluster(const cxxopts::ParseResult& args) {
  const std::string input = args["input"].as<std::string>();
  const std::string outDir = args["output"].as<std::string>();
  refuseOverlappingPaths({{"<input>", input}}, {{"-o", outDir, true}});
  ClusterStackOptions run;
  ClusteringOptions& options = run.clustering;
  const ClusteringArgs clustering = clusteringArgs(args);
  options.clusters = clustering.clusters.value_or(0);
  if (clustering.components) options.pca.components = *clustering.components;
  options.pca.powerIterations = args["power-iterations"].as<int>();
  options.pca.oversampling = args["oversampling"].as<int>();
  const int sampleMib = args["pca-sample"].as<int>();
  if (sampleMib < 0) throw Error("--pca-sample must be >= 0 (MiB; 0: every texel), got " + std::to_string(sampleMib));
  options.pca.sampleBytes = static_cast<std::size_t>(sampleMib) << 20;
  options.kmeans.maxIterations = args["max-iterations"].as<int>();
  if (clustering.seed) options.seed = *clustering.seed;
  const std::string representative = args["representative"].as<std::string>();
  if (representative == "median") options.representative = Representative::Median;
  else if (representative == "mean") options.representative = Representative::Mean;
  else throw Error("--representative: expected median or mean, got '" + representative + "'");
  run.space = clustering.space.value_or(kDefaultClusteringSpace);
  // Options that can be judged before hours of loading are judged now.
  if (options.clusters < 1) throw Error("--clusters must be at least 1, got " + std::to_string(options.clusters));
  if (options.pca.components < 1)
    throw Error("--components must be at least 1, got " + std::to_string(options.pca.components));
  if (options.pca.powerIterations < 0) throw Error("--power-iterations must be >= 0");
  if (options.pca.oversampling < 0) throw Error("--oversampling must be >= 0");
  if (options.kmeans.maxIterations < 0) throw Error("--max-iterations must be >= 0");

  checkFolderCreatable(outDir);  // created (with its parents) once there is something to write
  if (auto layout = layoutOption(args)) run.load.layout = *layout;
  if (auto crop = cropOption(args)) run.load.crop = *crop;
  const MemoryOptions memory = memoryOptions(args);
  run.memoryLimit = memory.limit;
  run.memoryLimitText = memory.limitText;
  run.stackStorage = memory.stack;
  run.progress = !Progress::quiet();

  const ClusterStackRun done = clusterStack(input, outDir, run);
  printSummary(done, writeClusterOutputs(done, run, outDir), run);
  return 0;
}

}  // namespace

int clusterMain(int argc, char** argv) {
  return runGuarded("cluster", [&] {
    cxxopts::Options options("nbtf cluster", "Cluster a BTF's ABRDFs (log + standardize, PCA, k-means++)");
    options.positional_help("<input> --clusters K -o <dir>");
    options.add_options()("input", "BTF stack folder or UBO2014 .btf file", cxxopts::value<std::string>())(
        "power-iterations", "PCA power iterations (more: closer to the exact PCA, one more read of the data each)",
        cxxopts::value<int>()->default_value(std::to_string(PcaOptions().powerIterations)))(
        "oversampling", "PCA sketch columns beyond --components",
        cxxopts::value<int>()->default_value(std::to_string(PcaOptions().oversampling)))(
        "pca-sample",
        "MiB of texels (as floats) PCA finds its subspace on when the input has at least 4 times as many; every "
        "texel is then projected onto it (0: every texel in every pass)",
        cxxopts::value<int>()->default_value(std::to_string(PcaOptions().sampleBytes >> 20)))(
        "max-iterations", "k-means iteration limit",
        cxxopts::value<int>()->default_value(std::to_string(KMeansOptions().maxIterations)))(
        "representative", "Cluster representative: median or mean",
        cxxopts::value<std::string>()->default_value("median"))(
        "o,output", "Output folder (labels.png, texel_colour.png, cluster_colour.png, summary.json)", cxxopts::value<std::string>());
    addClusteringOptions(options);
    addMemoryOptions(options);
    addStackOptions(options);
    cxxopts::ParseResult args;
    if (!parseCommand(options, "input", argc, argv, args)) return 0;
    if (!args.count("input")) throw Error("missing <input> (see 'nbtf cluster --help')");
    if (!args.count("clusters")) throw Error("missing --clusters K (see 'nbtf cluster --help')");
    if (!args.count("output")) throw Error("missing -o <dir> (see 'nbtf cluster --help')");
    return runCluster(args);
  });
}

}  // namespace nbtf::cli
