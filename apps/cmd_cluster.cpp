// nbtf cluster <input> --clusters K -o DIR: the clustering stage alone (log + standardize,
// PCA, k-means++ in the --space chosen, representatives), writing DIR/labels.png (the id list, a colour per
// cluster), DIR/texel_colour.png and DIR/cluster_colour.png (each texel's mean colour over all
// images, and its cluster's: what the clustering keeps) and DIR/summary.json.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>

#include "cli_common.h"
#include "cluster/cluster_output.h"
#include "cluster/clustering.h"
#include "commands.h"
#include "io/btf_loader.h"
#include "io/image_io.h"
#include "options/memory_options.h"
#include "pipeline/memory_estimate.h"
#include "preprocess/abrdf_source.h"
#include "util/atomic_file.h"
#include "util/memory.h"
#include "util/progress.h"
#include "util/timer.h"

namespace nbtf::cli {
namespace {

namespace fs = std::filesystem;


int clusterStack(const cxxopts::ParseResult& args) {
  const auto start = std::chrono::steady_clock::now();
  const std::string input = args["input"].as<std::string>();
  const std::string outDir = args["output"].as<std::string>();
  refuseOverlappingPaths({{"<input>", input}}, {{"-o", outDir, true}});
  ClusteringOptions options;
  options.clusters = args["clusters"].as<int>();
  options.pca.components = args["components"].as<int>();
  options.pca.powerIterations = args["power-iterations"].as<int>();
  options.pca.oversampling = args["oversampling"].as<int>();
  const int sampleMib = args["pca-sample"].as<int>();
  if (sampleMib < 0) throw Error("--pca-sample must be >= 0 (MiB; 0: every texel), got " + std::to_string(sampleMib));
  options.pca.sampleBytes = static_cast<std::size_t>(sampleMib) << 20;
  options.kmeans.maxIterations = args["max-iterations"].as<int>();
  options.seed = args["seed"].as<std::uint64_t>();
  const std::string representative = args["representative"].as<std::string>();
  if (representative == "median") options.representative = Representative::Median;
  else if (representative == "mean") options.representative = Representative::Mean;
  else throw Error("--representative: expected median or mean, got '" + representative + "'");
  const ClusteringSpace space = parseClusteringSpace(args["space"].as<std::string>(), "--space");
  // Options that can be judged before hours of loading are judged now.
  if (options.clusters < 1) throw Error("--clusters must be at least 1, got " + std::to_string(options.clusters));
  if (options.pca.components < 1)
    throw Error("--components must be at least 1, got " + std::to_string(options.pca.components));
  if (options.pca.powerIterations < 0) throw Error("--power-iterations must be >= 0");
  if (options.pca.oversampling < 0) throw Error("--oversampling must be >= 0");
  if (options.kmeans.maxIterations < 0) throw Error("--max-iterations must be >= 0");

  checkFolderCreatable(outDir);  // created (with its parents) once there is something to write
  const std::string labelsPath = (fs::path(outDir) / "labels.png").string();
  const std::string summaryPath = (fs::path(outDir) / "summary.json").string();
  const std::string texelColourPath = (fs::path(outDir) / "texel_colour.png").string();
  const std::string clusterColourPath = (fs::path(outDir) / "cluster_colour.png").string();

  ClusterRunInfo info;
  info.input = input;
  info.space = space;
  info.threads = threadCount();
  auto step = std::chrono::steady_clock::now();
  LoadOptions load;
  if (auto layout = layoutOption(args)) load.layout = *layout;
  if (auto crop = cropOption(args)) load.crop = *crop;
  // Refuse before loading what cannot fit (docs/compress.md, *Memory*).
  const MemoryOptions memory = memoryOptions(args);
  const std::size_t limit = memory.limit ? memory.limit : defaultMemoryLimit();
  load.expandUpTo = expandBudget(limit);
  {
    const StackShape shape = stackShape(input, load);
    MemoryEstimate estimate = estimateClusterMemory(shape, options.clusters, options.pca.components,
                                                    options.pca.oversampling, threadCount(), options.pca.sampleBytes);
    // The output folder may not exist yet: its nearest existing folder holds the scratch file.
    fs::path near = fs::absolute(outDir);
    while (!near.empty() && !fs::is_directory(near) && near != near.parent_path()) near = near.parent_path();
    load.scratchDir = stackScratchDir(memory.stack, near.string(), input, estimate, limit, !Progress::quiet());
    enforceMemoryLimit(estimate, limit, memory.limitText.empty() ? memoryLimitText(false, "") : memory.limitText,
                       input, shape);
  }
  BtfStack stack = loadBtfStack(input, load);
  info.loadSeconds = secondsSince(step);
  info.width = stack.width(), info.height = stack.height(), info.images = stack.numImages();
  info.crop = stack.crop;

  const int texels = stack.numTexels(), dims = 3 * stack.numImages();
  if (options.clusters > texels)
    throw Error("--clusters " + std::to_string(options.clusters) + ": the input has only " + std::to_string(texels) +
                " texels (" + std::to_string(stack.width()) + " x " + std::to_string(stack.height()) + ")");
  if (options.pca.components > std::min(texels, dims))
    throw Error("--components " + std::to_string(options.pca.components) + ": at most " +
                std::to_string(std::min(texels, dims)) + " for " + std::to_string(texels) + " texels x " +
                std::to_string(dims) + " dimensions");

  // The standardized ABRDF matrix is streamed from the 8-bit (or half) stack in slices
  // (preprocess/abrdf_source.h): it never exists whole.
  step = std::chrono::steady_clock::now();
  const Eigen::MatrixXf texelColour = texelMeanColour(stack);
  info.matrixSeconds = secondsSince(step);
  const int width = stack.width(), height = stack.height(), images = stack.numImages();
  step = std::chrono::steady_clock::now();
  ColumnMoments moments;  // spare PCA a pass over the stack, as alpha spares one (targetAlpha's)
  Standardization standardization = fitStandardization(stack, !Progress::quiet(), &info.alpha, &moments);
  StackAbrdfSource source(stack, std::move(standardization), std::move(moments));
  info.standardizeSeconds = secondsSince(step);

  ClusteringResult result = clusterAbrdfs(source, options, clusteringSpaceSource(stack, space, info.alpha).get());
  info.totalSeconds = secondsSince(start);
  const std::size_t peak = peakResidentBytes();
  info.peakMemoryBytes = peak;

  std::error_code ec;
  fs::create_directories(outDir, ec);
  if (ec) throw fileError(outDir, "cannot create output folder: " + ec.message());
  writeImage8(labelsPath, ImageFormat::Png, labelImage(result.ids, width, height));
  // Both appearance images on one scale (the brightest texel's average), so they compare.
  const float brightest = texelColour.maxCoeff();
  writeImage8(texelColourPath, ImageFormat::Png, colourImage(texelColour, width, height, brightest));
  writeImage8(clusterColourPath, ImageFormat::Png,
              colourImage(clusterMeanColour(texelColour, result.ids, options.clusters), width, height, brightest));
  nlohmann::json summary = clusteringSummary(result, options, info);
  summary["space"] = clusteringSpaceName(space);
  summary["appearance_images"] = {
      {"texel_colour", "texel_colour.png"},
      {"cluster_colour", "cluster_colour.png"},
      {"encoding", "linear RGB averaged over all images, divided by scale_linear, sRGB 8-bit"},
      {"scale_linear", brightest}};
  writeFileAtomic(summaryPath, summary.dump(2) + "\n");

  const auto& sizes = summary["cluster_sizes"];
  std::printf("clustered %d texels (%d x %d, %d images) into %d clusters in %.2f s\n", texels, width, height, images,
              options.clusters, info.totalSeconds);
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
  std::printf("  memory       peak %s resident (--memory-limit %s)\n", formatBytes(peak).c_str(),
              formatBytes(limit).c_str());
  std::printf("  wrote        %s (ids), %s and %s (mean colour per texel / per cluster), %s\n",
              labelsPath.c_str(), texelColourPath.c_str(), clusterColourPath.c_str(), summaryPath.c_str());
  return 0;
}

}  // namespace

int clusterMain(int argc, char** argv) {
  return runGuarded("cluster", [&] {
    cxxopts::Options options("nbtf cluster", "Cluster a BTF's ABRDFs (log + standardize, PCA, k-means++)");
    options.positional_help("<input> --clusters K -o <dir>");
    options.add_options()("input", "BTF stack folder or UBO2014 .btf file", cxxopts::value<std::string>())(
        "k,clusters", "Number of clusters", cxxopts::value<int>())(
        "components", "PCA components", cxxopts::value<int>()->default_value("32"))(
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
        "space",
        "Values PCA and k-means work on: log (standardized log ABRDFs) or linear (linear / alpha); the "
        "representatives are medians of the standardized log ABRDFs either way",
        cxxopts::value<std::string>()->default_value(clusteringSpaceName(kDefaultClusteringSpace)))(
        "seed", "Random seed (same seed, same clusters)", cxxopts::value<std::uint64_t>()->default_value("1"))(
        "o,output", "Output folder (labels.png, texel_colour.png, cluster_colour.png, summary.json)", cxxopts::value<std::string>());
    addMemoryOptions(options);
    addStackOptions(options);
    cxxopts::ParseResult args;
    if (!parseCommand(options, "input", argc, argv, args)) return 0;
    if (!args.count("input")) throw Error("missing <input> (see 'nbtf cluster --help')");
    if (!args.count("clusters")) throw Error("missing --clusters K (see 'nbtf cluster --help')");
    if (!args.count("output")) throw Error("missing -o <dir> (see 'nbtf cluster --help')");
    return clusterStack(args);
  });
}

}  // namespace nbtf::cli
