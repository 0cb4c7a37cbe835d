#include "pipeline/compressor.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>

#include "codec/methods/method.h"
#include "model/trainer.h"
#include "pipeline/adaptive.h"
#include "pipeline/compress_parts.h"
#include "pipeline/memory_estimate.h"
#include "pipeline/neural_compressor.h"
#include "pipeline/pca_compressor.h"
#include "pipeline/size_budget.h"
#include "util/atomic_file.h"
#include "util/error.h"
#include "util/memory.h"
#include "util/parallel.h"
#include "util/timer.h"

namespace nbtf {
namespace {

std::string checkpointPathFor(const std::string& output, const CompressOptions& o) {
  if (!o.checkpointPath.empty()) return o.checkpointPath;
  if (!o.train.checkpointPath.empty()) return o.train.checkpointPath;
  return defaultCheckpointPath(output);
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

// The budget's estimate is an upper bound of the file; should a file still exceed it, it is
// not written (the checkpoint stays), rather than broken the budget's promise.
void refuseOverBudget(const CompressedBtf& btf, const CompressOptions& o, const CompressStats& stats) {
  if (o.sizeBudget == 0 || o.adaptive.enabled) return;
  const std::uint64_t bytes = serializeNbtf(btf).size();
  if (bytes > o.sizeBudget)
    throw Error("--size-budget " + std::to_string(o.sizeBudget) + " bytes: the trained file is " +
                std::to_string(bytes) + " bytes, above the " + std::to_string(stats.sizeBudgetEstimate) +
                " estimated before loading (an internal error); nothing written, run again with a smaller budget");
}

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

// The compressor of each model kind (codec/methods/method.h), by the kind the options make.
struct KindCompressor {
  CodecMethod method;
  CompressedBtf (*compress)(const BtfStack&, const CompressOptions&, CompressStats&);
};
const KindCompressor kCompressors[] = {
    {CodecMethod::ClusteredNeural, detail::compressNeuralStack},
    {CodecMethod::PerTexelNeural, detail::compressNeuralStack},
    {CodecMethod::Pca, compressPcaStack},
};

}  // namespace

CodecMethod compressMethod(const CompressOptions& options) {
  if (options.pcaBaseline) return CodecMethod::Pca;
  return options.clusters > 0 ? CodecMethod::ClusteredNeural : CodecMethod::PerTexelNeural;
}

CompressedBtf compressStack(const BtfStack& stack, const CompressOptions& options, CompressStats& stats) {
  const CodecMethod method = compressMethod(options);
  for (const KindCompressor& c : kCompressors)
    if (c.method == method) return c.compress(stack, options, stats);
  throw Error("no compressor for method " + codecMethodName(method));
}

std::string defaultCheckpointPath(const std::string& output) { return output + ".ckpt"; }

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
    if (o.pcaComponents < 1 && o.sizeBudget == 0)
      throw Error("--method pca needs --components C >= 1 (the principal components kept), got " +
                  std::to_string(o.pcaComponents));
  } else {
    o.checkpointPath = checkpointPathFor(output, options);
    checkWritable(o.checkpointPath);
    refuseOrRestartCheckpoint(o);
  }
  CompressStats stats;
  stats.output = output;
  // ---- The input, resolved once (listing, first image, crop, shape); then fail before loading
  // when the run cannot fit in --memory-limit.
  stats.memoryLimit = o.memoryLimit > 0 ? o.memoryLimit : defaultMemoryLimit();
  o.load.expandUpTo = expandBudget(stats.memoryLimit);
  const BtfInput in = resolveBtfInput(input, o.load);  // a crop outside the images is that, not a cluster-count error
  const StackShape& shape = in.shape;                  // the crop's texels when cropped
  if (!o.pcaBaseline) refuseTooFewTexels(shape, input);
  chooseSizeBudgetPoint(in, o, stats);  // k (PCA: C) and, without --config, the recipe
  detail::resolveDefaultClusters(o, shape.texels(), stats);
  if (in.cropped && !o.pcaBaseline) detail::checkClusterCounts(o, shape.texels(), "the crop");
  const bool modulated = o.clusters > 0 && o.train.modulation.mode != "none";
  MemoryEstimate estimate = estimateCompressMemory(
      shape, o.clusters, o.pcaBaseline, o.pcaComponents > 0 ? o.pcaComponents : detail::kDefaultPcaComponents,
      PcaOptions().oversampling, modulated ? o.train.modulation.terms * o.train.modulation.channels : 1, threadCount());
  const std::string outputDir = std::filesystem::path(output).parent_path().string();
  o.load.scratchDir = placeStackWithinLimit(o.stackStorage, outputDir, input, shape, estimate, stats.memoryLimit,
                                            o.memoryLimitText, o.progress);
  stats.stackScratchDir = o.load.scratchDir;
  stats.memoryEstimate = estimate.total();

  auto t = Clock::now();
  LoadOptions load = o.load;
  load.progress = load.progress && o.progress;
  BtfStack stack = loadBtfStack(in, load);
  stats.seconds.load = secondsSince(t);
  stats.computedStack = stack.isComputed();
  if (detail::stopRequested(o)) {
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
  refuseOverBudget(btf, o, stats);
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

}  // namespace nbtf
