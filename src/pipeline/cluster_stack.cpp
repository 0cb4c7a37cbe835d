#include "pipeline/cluster_stack.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <utility>

#include "io/image_io.h"
#include "preprocess/abrdf_source.h"
#include "util/atomic_file.h"
#include "util/error.h"
#include "util/memory.h"
#include "util/parallel.h"
#include "util/timer.h"

namespace nbtf {
namespace fs = std::filesystem;

namespace {

void checkCounts(const BtfStack& stack, const ClusteringOptions& options) {
  const int texels = stack.numTexels(), dims = 3 * stack.numImages();
  if (options.clusters > texels)
    throw Error("--clusters " + std::to_string(options.clusters) + ": the input has only " + std::to_string(texels) +
                " texels (" + std::to_string(stack.width()) + " x " + std::to_string(stack.height()) + ")");
  if (options.pca.components > std::min(texels, dims))
    throw Error("--components " + std::to_string(options.pca.components) + ": at most " +
                std::to_string(std::min(texels, dims)) + " for " + std::to_string(texels) + " texels x " +
                std::to_string(dims) + " dimensions");
}

}  // namespace

ClusterStackRun clusterStack(const std::string& input, const std::string& outDir, const ClusterStackOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  const ClusteringOptions& clustering = options.clustering;
  ClusterStackRun run;
  ClusterRunInfo& info = run.info;
  info.input = input;
  info.space = options.space;
  info.threads = threadCount();
  auto step = std::chrono::steady_clock::now();
  LoadOptions load = options.load;
  run.memoryLimit = options.memoryLimit ? options.memoryLimit : defaultMemoryLimit();
  load.expandUpTo = expandBudget(run.memoryLimit);
  const BtfInput in = resolveBtfInput(input, load);
  {
    const StackShape& shape = in.shape;
    MemoryEstimate estimate = estimateClusterMemory(shape, clustering.clusters, clustering.pca.components,
                                                    clustering.pca.oversampling, threadCount(),
                                                    clustering.pca.sampleBytes);
    // The output folder may not exist yet: its nearest existing folder holds the scratch file.
    fs::path near = fs::absolute(outDir);
    while (!near.empty() && !fs::is_directory(near) && near != near.parent_path()) near = near.parent_path();
    load.scratchDir = placeStackWithinLimit(options.stackStorage, near.string(), input, shape, estimate,
                                            run.memoryLimit, options.memoryLimitText, options.progress);
  }
  BtfStack stack = loadBtfStack(in, load);
  info.loadSeconds = secondsSince(step);
  info.width = stack.width(), info.height = stack.height(), info.images = stack.numImages();
  info.crop = stack.crop;
  checkCounts(stack, clustering);

  // The standardized ABRDF matrix is streamed from the 8-bit (or half) stack in slices
  // (preprocess/abrdf_source.h): it never exists whole.
  step = std::chrono::steady_clock::now();
  run.texelColour = texelMeanColour(stack);
  info.matrixSeconds = secondsSince(step);
  step = std::chrono::steady_clock::now();
  ColumnMoments moments;  // spare PCA a pass over the stack, as alpha spares one (targetAlpha's)
  Standardization standardization = fitStandardization(stack, options.progress, &info.alpha, &moments);
  StackAbrdfSource source(stack, std::move(standardization), std::move(moments));
  info.standardizeSeconds = secondsSince(step);

  run.result = clusterAbrdfs(source, clustering, clusteringSpaceSource(stack, options.space, info.alpha).get());
  info.totalSeconds = secondsSince(start);
  info.peakMemoryBytes = peakResidentBytes();
  return run;
}

ClusterOutputFiles writeClusterOutputs(const ClusterStackRun& run, const ClusterStackOptions& options,
                                       const std::string& outDir) {
  ClusterOutputFiles files;
  files.labels = (fs::path(outDir) / "labels.png").string();
  files.summary = (fs::path(outDir) / "summary.json").string();
  files.texelColour = (fs::path(outDir) / "texel_colour.png").string();
  files.clusterColour = (fs::path(outDir) / "cluster_colour.png").string();
  std::error_code ec;
  fs::create_directories(outDir, ec);
  if (ec) throw fileError(outDir, "cannot create output folder: " + ec.message());
  const int width = run.info.width, height = run.info.height;
  writeImage8(files.labels, ImageFormat::Png, labelImage(run.result.ids, width, height));
  // Both appearance images on one scale (the brightest texel's average), so they compare.
  const float brightest = run.texelColour.maxCoeff();
  writeImage8(files.texelColour, ImageFormat::Png, colourImage(run.texelColour, width, height, brightest));
  writeImage8(files.clusterColour, ImageFormat::Png,
              colourImage(clusterMeanColour(run.texelColour, run.result.ids, options.clustering.clusters), width,
                          height, brightest));
  files.summaryJson = clusteringSummary(run.result, options.clustering, run.info);
  files.summaryJson["space"] = clusteringSpaceName(options.space);
  files.summaryJson["appearance_images"] = {
      {"texel_colour", "texel_colour.png"},
      {"cluster_colour", "cluster_colour.png"},
      {"encoding", "linear RGB averaged over all images, divided by scale_linear, sRGB 8-bit"},
      {"scale_linear", brightest}};
  writeFileAtomic(files.summary, files.summaryJson.dump(2) + "\n");
  return files;
}

}  // namespace nbtf
