// The compression pipeline behind `nbtf compress`: memory estimate (--memory-limit) -> load ->
// standardization statistics -> (clustered) PCA + k-means++ + representatives over the ABRDF
// matrix streamed from the stack (preprocess/abrdf_source.h) | (per-texel) the standardized
// matrix itself -> train the encoder/decoder -> CompressedBtf -> .nbtf (atomic write).
// The PCA baseline (pcaBaseline) replaces everything after loading: pipeline/pca_compressor.h.
// Deterministic for a seed and thread count.
#pragma once
#include <atomic>
#include <string>
#include <vector>

#include "cluster/clustering.h"
#include "codec/nbtf_file.h"
#include "io/btf_loader.h"
#include "pipeline/memory_estimate.h"
#include "model/trainer.h"
#include "util/path_guard.h"

namespace nbtf {

// Adaptive clusters (pipeline/adaptive.h, docs/compress.md): training runs in stages over
// one schedule; between stages the clusters with the largest share of the error are split
// (2-means in PCA space) and clusters whose latents decode to nearly the same values are
// merged, until the target or the budget is met.
struct AdaptiveOptions {
  bool enabled = false;
  double targetRmse = 0;         // no more splits once a stage's decoded training RMSE is at most this (0 = none)
  int maxClusters = 0;           // cap on k (0 = none); with neither cap nor budget k at most doubles per stage
  std::uint64_t sizeBudget = 0;  // the written .nbtf is never larger (bytes; 0 = none)
  int initialClusters = 0;       // k of the first stage; 0 = (max clusters, else --clusters) / 2^(stages - 1)
  int stages = 5;                // training stages; the clusters change between them (1..20)
  double growthFraction = 0.6;   // the stages before the last end at even fractions of this share of the steps
  // Merge two clusters when merging them costs less than this fraction of the mean cluster's
  // error (n_c n_d / (n_c + n_d) x their decoded terms' squared difference, training images).
  double mergeTolerance = 0.02;
};

// One stage of an adaptive run.
struct AdaptiveStage {
  int clusters = 0;             // k trained in this stage
  std::int64_t steps = 0;       // optimizer steps done at its end (the schedule's step count)
  double rmseTrain = -1;        // decoded RMSE of this stage's model, training images (eq. 10)
  std::uint64_t bytes = 0;      // .nbtf size of this stage's model
  int splits = 0, merges = 0, pruned = 0;  // edits made after this stage
};

// The default k (configs/default.json's "clustering": {"clusters"}): about 1:10,000 at
// 100 x 100 texels (docs/model.md, *How many clusters the default uses*).
constexpr int kDefaultClusters = 1000;
// A default k is capped to the input: at most one cluster per this many texels, so that a small
// input (a crop, a test patch) gets clusters that still group texels, not an error.
constexpr int kTexelsPerDefaultCluster = 10;
// The k a default of `configured` clusters gives on `texels` texels: min(configured,
// max(1, texels / kTexelsPerDefaultCluster)); 0 (per-texel) stays 0.
int defaultClusterCount(int configured, std::int64_t texels);

struct CompressOptions {
  LoadOptions load;             // layout, crop
  TrainConfig train;            // the recipe, with command-line overrides already applied
  int clusters = kDefaultClusters;  // k; 0 = per-texel mode (one latent per texel)
  // k is the config's default, not asked for (no --clusters): capped to the input by
  // defaultClusterCount once the texel count is known. An asked-for k above the texel count is an error.
  bool clustersAreDefault = false;
  // With clustersAreDefault: k = max(1, round(texels / this)) instead of `clusters` capped (the
  // config's "clustering.texels_per_cluster"; 0 = not given).
  double texelsPerCluster = 0;
  // The classic PCA baseline instead of a neural method: pcaComponents components (>= 1),
  // no training; uses train.seed and train.holdoutFraction only.
  bool pcaBaseline = false;
  int pcaComponents = 0;        // PCA components (before k-means, or of the baseline); 0 = default (32, capped by the data)
  int kmeansIterations = 0;     // Lloyd rounds at most; 0 = the clustering library's default
  // The values PCA and k-means find the clusters in (the representatives are always medians of
  // the standardized log ABRDFs, the encoder's input).
  ClusteringSpace clusteringSpace = kDefaultClusteringSpace;
  std::string saveEncoderPath;  // also write this .nbtf with the encoder inside ("" = no)
  // Where training checkpoints go; "" = the config's training.checkpoint_path, else
  // defaultCheckpointPath(output), which is removed once the output is written.
  std::string checkpointPath;
  // An existing checkpoint (or adaptive state) beside it is an interrupted run's work:
  // compressBtf refuses to start over it unless train.resume continues it or `restart` deletes it.
  bool restart = false;
  bool progress = true;
  std::atomic<bool>* stopFlag = nullptr;  // set (SIGINT) -> checkpoint, stop, write nothing
  AdaptiveOptions adaptive;     // clustered only
  // compressBtf refuses, before loading, a run whose estimated peak memory
  // (pipeline/memory_estimate.h) is above this many bytes; 0 = defaultMemoryLimit() (75% of
  // physical memory). memoryLimitText: how the limit was given, for the error ("" = default).
  std::size_t memoryLimit = 0;
  std::string memoryLimitText;
  // Where an image stack's samples live (memory_estimate.h); the scratch folder defaults to
  // the output's.
  StackStorageOptions stackStorage;
  // --size-budget without --adaptive (pipeline/size_budget.h): the written file is at most this
  // many bytes; k (PCA: the components) is the largest whose file fits. 0 = no budget.
  std::uint64_t sizeBudget = 0;
  // With sizeBudget and no --config: the named configs' options in the order of their files'
  // sizes, the command line applied to each; the budget takes the largest whose takeover point
  // fits.
  std::vector<CompressOptions> sizeBudgetCurve;
  // As a recipe of sizeBudgetCurve, its takeover point: this many times its own k (capped at the
  // densest). A richer recipe with few clusters is behind a plainer one with many at the same
  // size (docs/compress.md, *A size budget*), so the budget takes it only once it fits there.
  int sizeBudgetTakeover = 1;
};

// Wall-clock seconds per stage. The cluster stage's parts (clustered runs without --adaptive)
// let the cost model (docs/model.md) follow each one as the material grows.
struct StageSeconds {
  double load = 0, preprocess = 0, cluster = 0, train = 0, write = 0;
  double pca = 0;  // PCA baseline: fit, coefficients, hold-out interpolation and the RMSE measurement
  double assemble = 0;  // after training: storage rounding, the modulation refit, the decoded RMSE
  struct {
    double pca = 0, kmeans = 0, medians = 0;
    double coefficients = 0;  // per-texel modulation coefficients and the floor RMSE
  } clusterParts;
  // The training stage's steps by phase (neural runs without --adaptive; TrainResult::Profile).
  // The rest of `train` is set-up and the exact evaluation at the end.
  TrainResult::Profile trainParts;
  double total() const { return load + preprocess + cluster + train + assemble + write + pca; }
};

struct CompressStats {
  std::string output;
  CodecMethod method = CodecMethod::ClusteredNeural;
  int clusters = 0;           // k; 0 in per-texel mode and for PCA
  int clustersConfigured = 0;  // the config's default k when the input capped it below (else 0)
  double texelsPerCluster = 0;  // the config's texels per cluster k came from (else 0)
  // --size-budget without --adaptive: the budget, the config it chose ("" = the one given) and
  // the bytes estimated for the chosen k before loading (an upper bound of the file); 0 = none.
  std::uint64_t sizeBudget = 0, sizeBudgetEstimate = 0;
  std::string sizeBudgetConfig;
  bool sizeBudgetAtDensest = false;  // k stopped at one cluster per kDensestTexelsPerCluster, below the budget
  int pcaComponents = 0;      // PCA components: before k-means (clustered) or kept (baseline); 0 per-texel
  int kmeansIterations = 0;   // Lloyd rounds of the initial clustering (clustered only)
  std::string clusteringSpace;  // "log" or "linear" (clustered only; else empty)
  int texels = 0, images = 0, holdoutImages = 0;
  float alpha = 1;
  // RMSE of eq. (10) over texels x images x channels, on linear RGB divided by alpha.
  double rmseTrain = -1;      // on the training images
  double rmseHoldout = -1;    // on the held-out images; -1 when there are none
  // Clustered: the floors on the training images (same space): the RMSE of the best model with
  // one value per cluster and image (the cluster means), and with the per-texel modulation too
  // (the coefficients the terms were trained with).
  double rmseFloor = -1, rmseFloorModulated = -1;
  std::string modulationMode = "none";  // modulation.mode of the config
  int modulationTerms = 0, modulationChannels = 1, modulationBits = 0;
  NbtfSizes sizes;            // fileBytes filled once written
  StageSeconds seconds;
  int epochs = 0;
  std::int64_t steps = 0;
  double samplesPerSecond = 0, decoderGflops = 0;
  std::string products = "float";  // the decoder pass's products (TrainResult::products)
  // Clustered: of the ABRDFs in the clustering space; PCA baseline: of the fitted linear ABRDFs / alpha.
  double pcaExplainedVarianceRatio = -1;  // -1 in per-texel mode
  bool interrupted = false;   // stopped by stopFlag: nothing written, checkpoint kept
  // Data-parallel training (train.distributed): processes, whether this one is a worker
  // (rank > 0: it trains its shares, rank 0 writes the file), and the gradient traffic.
  int worldSize = 1;
  bool worker = false;
  double allReduceBytesPerStep = 0, allReduceSecondsPerStep = 0;
  std::string checkpointPath;
  std::vector<AdaptiveStage> adaptiveStages;  // empty unless --adaptive
  std::string adaptiveStopReason;             // why the clusters stopped growing
  // Memory (compressBtf): the estimate checked before loading, the limit, and the peak
  // resident set size at the end (getrusage), bytes; 0 = not measured (compressStack alone).
  std::size_t memoryEstimate = 0, memoryLimit = 0, peakMemory = 0;
  bool computedStack = false;  // a UBO2014 input kept factorized (values computed when read)
  std::string stackScratchDir;  // the folder of the stack's scratch file ("" = the stack was in memory)
};

// The model kind the options make: PCA with pcaBaseline (--method pca), clustered with
// clusters > 0, per-texel with 0. compressStack runs that kind's compressor.
CodecMethod compressMethod(const CompressOptions& options);

// The in-memory part: stack -> compressed material (no file I/O except checkpoints).
// Fills `stats` (all but the write stage and fileBytes).
CompressedBtf compressStack(const BtfStack& stack, const CompressOptions& options, CompressStats& stats);

// The whole pipeline. Checks that `output` (and the encoder file) can be written before
// any work is done. When interrupted, returns with stats.interrupted set and writes nothing.
CompressStats compressBtf(const std::string& input, const std::string& output, const CompressOptions& options);

// The paths a compress run reads and writes, by the option that names them: the input and
// the config it was given (`configPath`, may be empty) as inputs; -o, --save-encoder, the
// checkpoint and its adaptive state, and `extraOutputs` (--stats-json) as outputs.
// refuseOverlappingPaths (util/path_guard.h) over them is compressBtf's first check.
void refuseOverlappingCompressPaths(const std::string& input, const std::string& output, const CompressOptions& options,
                                    const std::string& configPath = "",
                                    const std::vector<PathUse>& extraOutputs = {});

// "<output>.ckpt": where training checkpoints go unless configured otherwise.
std::string defaultCheckpointPath(const std::string& output);

// The final summary table (sizes, ratio, RMSE and its space, time per stage).
std::string formatCompressSummary(const CompressStats& stats);
// The same as JSON: rmse_train, rmse_holdout (null when none), ratio,
// bytes {decoder, latents, ids, total, raw_float32, file} (PCA: {pca_mean, pca_basis,
// pca_coefficients, total, raw_float32, file}), seconds {load, preprocess, cluster, train,
// pca, write, total}, and context keys (method, clusters, pca_components, texels, ...).
std::string compressStatsJson(const CompressStats& stats);


}  // namespace nbtf
