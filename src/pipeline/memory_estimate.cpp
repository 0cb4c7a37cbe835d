#include "pipeline/memory_estimate.h"

#include <algorithm>
#include <iostream>
#include <sstream>

#include "cluster/cluster_values.h"
#include "cluster/pca.h"
#include "io/ubo2014_btf.h"
#include "preprocess/abrdf_source.h"
#include "util/error.h"
#include "util/memory.h"
#include "util/parallel.h"
#include "util/scratch_mapping.h"

namespace nbtf {

namespace {

constexpr std::size_t kFloat = sizeof(float);
// The process before any data: libtorch, OpenCV, OpenBLAS and their arenas (about 100 MiB
// resident, measured), with allocator slack and the training's own arrays.
constexpr std::size_t kProcess = std::size_t(256) << 20;

struct Stage {
  std::size_t bytes = 0;
  const char* name = "";
};

// Clustering from the stack: the source's tables and slices, the PCA's texels x sketch and
// 3N x sketch matrices (a few alive at once: Q, the product, the QR's copy; on a large
// material its sample of texels instead), k-means' scores.
Stage clusteringStage(const StackShape& shape, int components, int oversampling, int workers,
                      std::size_t pcaSampleBytes = PcaOptions().sampleBytes) {
  const std::size_t m = static_cast<std::size_t>(shape.texels()), d = 3 * static_cast<std::size_t>(shape.images());
  const std::size_t sketch = static_cast<std::size_t>(std::max(1, components + oversampling));
  const std::size_t source = StackAbrdfSource::workingBytes(shape.texels(), shape.images(), shape.type, workers);
  // Sampling (cluster/pca.h): the sample and its small products, then the texels x sketch
  // projection; never both at once.
  PcaOptions pcaOptions;
  pcaOptions.components = components;
  pcaOptions.oversampling = oversampling;
  pcaOptions.sampleBytes = pcaSampleBytes;
  const auto dims = static_cast<Eigen::Index>(d);
  const std::size_t sample =
      pcaOptions.samples(shape.texels(), dims) ? static_cast<std::size_t>(pcaOptions.sampleRows(dims)) : 0;
  const std::size_t products = sample ? std::max((sample * d + 4 * sample * sketch) * kFloat, 2 * m * sketch * kFloat)
                                      : 4 * m * sketch * kFloat;
  const std::size_t pca = products + 4 * d * sketch * kFloat;
  const std::size_t kmeans = 3 * m * static_cast<std::size_t>(std::max(1, components)) * kFloat + 32 * m;
  return {source + pca + kmeans, "PCA of the streamed ABRDF matrix"};
}

// Per-texel modulation coefficients: per thread, a batch's share of clusters' ABRDFs as the stack
// stores them (the bytes of modulationTexelsPerThread texels as floats), one such cluster as
// floats for its SVD, its Gram matrix when it is small; the texels' coefficients.
Stage modulationStage(const StackShape& shape, int clusters, int coefficientsPerTexel, int workers) {
  const std::size_t m = static_cast<std::size_t>(shape.texels()), d = 3 * static_cast<std::size_t>(shape.images());
  const std::size_t large = modulationTexelsPerThread(shape.texels(), clusters);
  const std::size_t side = std::min<std::size_t>(std::min(large, d), kExactSvdUpTo);  // the exact SVD's Gram matrix
  const std::size_t perWorker = 2 * large * d * kFloat + side * side * 8 * 2;
  const std::size_t perTexel = m * static_cast<std::size_t>(std::max(1, coefficientsPerTexel)) * kFloat * 4 + m * 3 * kFloat * 2;
  return {static_cast<std::size_t>(std::max(1, workers)) * perWorker + perTexel, "per-texel modulation coefficients"};
}

}  // namespace

MemoryEstimate estimateCompressMemory(const StackShape& shape, int clusters, bool pcaBaseline, int components,
                                      int oversampling, int coefficientsPerTexel, int workers) {
  MemoryEstimate e;
  e.stack = shape.stackBytes();
  e.process = kProcess;
  const std::size_t m = static_cast<std::size_t>(shape.texels()), d = 3 * static_cast<std::size_t>(shape.images());
  const std::size_t matrix = m * d * kFloat;
  if (pcaBaseline || clusters <= 0) {
    // The M x 3N float32 matrix in memory, plus a copy's worth of working space (the
    // per-texel encoder's inputs, the baseline's products).
    e.working = matrix + matrix / 4 + m * 3 * kFloat * static_cast<std::size_t>(std::max(1, workers));
    e.stage = pcaBaseline ? "the PCA baseline's M x 3N float32 matrix" : "the per-texel mode's M x 3N float32 matrix";
    return e;
  }
  Stage a = clusteringStage(shape, components, oversampling, workers);
  Stage b = modulationStage(shape, clusters, coefficientsPerTexel, workers);
  const Stage& top = a.bytes >= b.bytes ? a : b;
  e.working = top.bytes;
  e.stage = top.name;
  return e;
}

MemoryEstimate withStackInScratchFile(MemoryEstimate e) {
  e.stack = std::min(e.stack, kScratchResidentWindow);
  e.stackInScratchFile = true;
  return e;
}

std::string stackScratchDir(const StackStorageOptions& options, const std::string& defaultDir,
                            const std::string& input, MemoryEstimate& estimate, std::size_t limit, bool announce) {
  if (looksLikeUbo2014(input) || options.storage == StackStorage::Memory) return "";
  std::string dir = options.scratchDir.empty() ? defaultDir : options.scratchDir;
  if (dir.empty()) dir = ".";
  const MemoryEstimate inFile = withStackInScratchFile(estimate);
  if (options.storage == StackStorage::File) {
    if (announce && isMemoryFileSystem(dir))
      std::cerr << "note: " << dir << " is a file system in memory: the stack's scratch file there takes as much "
                << "memory as the stack (choose a folder on disk with --scratch-dir)\n";
  } else {
    if (estimate.total() <= limit || inFile.total() > limit || isMemoryFileSystem(dir)) return "";
    if (announce)
      std::cerr << "stack: its " << formatBytes(estimate.stack) << " go to a scratch file in " << dir
                << " (in memory the run would need about " << formatBytes(estimate.total())
                << ", over the limit of " << formatBytes(limit) << ")\n";
  }
  estimate = inFile;
  return dir;
}

MemoryEstimate estimateClusterMemory(const StackShape& shape, int clusters, int components, int oversampling,
                                     int workers, std::size_t pcaSampleBytes) {
  (void)clusters;
  MemoryEstimate e;
  e.stack = shape.stackBytes();
  e.process = kProcess;
  Stage a = clusteringStage(shape, components, oversampling, workers, pcaSampleBytes);
  e.working = a.bytes;
  e.stage = a.name;
  return e;
}

void enforceMemoryLimit(const MemoryEstimate& e, std::size_t limit, const std::string& limitText,
                        const std::string& input, const StackShape& shape) {
  if (e.total() <= limit) return;
  std::ostringstream s;
  s << shape.width << " x " << shape.height << " texels x " << shape.images() << " images ("
    << (shape.computedBytes ? "computed from UBO2014 factors" : shape.type == SampleType::Srgb8 ? "8-bit" : "half float")
    << ") need about " << formatBytes(e.total()) << " of memory: "
    << (e.stackInScratchFile ? "the stack's pages in use (it is in a scratch file) " : "the stack ")
    << formatBytes(e.stack) << " + " << formatBytes(e.working) << " for the "
    << e.stage << " + " << formatBytes(e.process) << " for the program; " << limitText << " allows "
    << formatBytes(limit);
  if (e.stack + e.process > limit)
    s << ": the stack and the program alone do not fit. Compress a part of it (--crop X,Y,W,H) or raise "
         "--memory-limit";
  else
    s << ". Raise --memory-limit, or compress a part of it (--crop X,Y,W,H)";
  throw fileError(input, s.str());
}

std::string memoryLimitText(bool given, const std::string& value) {
  if (given) return "--memory-limit " + value;
  return "the default --memory-limit (75% of the " + formatBytes(physicalMemoryBytes()) + " of physical memory)";
}

std::string placeStackWithinLimit(const StackStorageOptions& storage, const std::string& defaultDir,
                                  const std::string& input, const StackShape& shape, MemoryEstimate& estimate,
                                  std::size_t limit, const std::string& limitText, bool announce) {
  std::string dir = stackScratchDir(storage, defaultDir, input, estimate, limit, announce);
  enforceMemoryLimit(estimate, limit, limitText.empty() ? memoryLimitText(false, "") : limitText, input, shape);
  return dir;
}

}  // namespace nbtf
