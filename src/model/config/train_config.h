// The training recipe: the network's shape, the optimizer, the schedule, how the parts are
// stored, and the run's controls (configs/*.json, one object per component; docs/model.md),
// with its reader, checks and writer (train_config.cpp) and the step plan it gives. Torch-free.
#pragma once
#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "codec/mlp.h"
#include "model/distributed/distributed.h"
#include "util/direction_planes.h"
#include "util/directions.h"

namespace nbtf {

// Network shape. Defaults are the paper's (8-dim latent, 4 linear decoder layers of 106);
// the encoder's channel widths are ours (the paper gives none).
struct ModelConfig {
  int latentDim = 8;
  // One conv block (Conv1d k3 s1 p1 -> MaxPool1d k3 s3 -> BatchNorm1d) per entry, at most:
  // fewer are used when the ABRDF is too short (see encoderBlockCount).
  std::vector<int> encoderChannels = {4, 8, 16};
  int decoderWidth = 106;
  int decoderLayers = 4;  // linear layers, ReLU between, linear RGB output
  // RGB terms the decoder outputs: 1, or R with per-texel modulation of R terms (set by the
  // compress pipeline from the "modulation" object, not a config key of its own).
  int outputTerms = 1;
  // The decoder's direction input (util/directions.h): the paper's 4 stereographic
  // coordinates, those plus the half vector and cos(theta_d) (8), or those plus their sines
  // and cosines at 3 octaves (28) or 2 (20, the default: docs/model.md, *Direction inputs*).
  DirectionEncoding directionInputs = DirectionEncoding::StereographicFourier2;
  // Learned direction planes (util/direction_planes.h; the "direction_planes" object:
  // "resolution" R, "features" F; F = 0: none): 3 F more decoder inputs after the fixed ones.
  int planeResolution = 8;
  int planeFeatures = 4;
  // Per-cluster direction planes ("cluster_planes": "resolution", "features"; 0 = none): each
  // encoder input (cluster) has its own three R x R grids of G features; 3 G more inputs.
  int clusterPlaneResolution = 6;
  int clusterPlaneFeatures = 0;
  // The decoder's direction inputs: the fixed encoding's, then the planes', then the cluster planes'.
  int directionInputCount() const {
    return nbtf::directionInputCount(directionInputs) + DirectionPlanes::kPlanes * planeFeatures +
           DirectionPlanes::kPlanes * clusterPlaneFeatures;
  }
};

// Conv blocks actually used for N images: as many of `configured` as keep the pooled
// length >= 2 (6561 -> 2187 -> 729 -> 243 with 3 blocks; 4 images -> 0 blocks).
int encoderBlockCount(int imageCount, int configured);
// The channel widths of the blocks actually used: the configured ones, fewer for short
// ABRDFs (encoderBlockCount), and for more images than the 81 x 81 sampling (6561) the recipe
// was made for, more blocks, each twice as wide as the one before, as long as the next block
// still leaves at least 243 positions (what 6561 images pool to with the default 3 blocks). UBO2014's
// 22,801 images: 7600 -> 2533 -> 844 -> 281 with {4, 8, 16, 32}, the 4 blocks the paper's
// predecessor used there; 6561 images or fewer: unchanged.
std::vector<int> encoderWidths(int imageCount, const std::vector<int>& configured);
// The decoder as an Mlp shape (input latent + direction inputs, RGB out), weights zero; 24,383 parameters
// for the defaults.
Mlp decoderShape(const ModelConfig& model);

// Per-texel modulation (beyond the paper; codec/texel_modulation.h, cluster/cluster_values.h):
// the "modulation" object of a config. Clustered mode only.
// Defaults (= configs/default.json): 1 term with one coefficient per RGB channel (a colour
// factor per texel), 6-bit codes, the refit keeping each texel's mean as one image's worth;
// configs/paper-clustered.json: "none".
struct ModulationConfig {
  std::string mode = "svd";   // "none" | "svd" (coefficients of a per-cluster rank-`terms` SVD of the data)
  int terms = 1;              // RGB terms per cluster, each texel mixing them with its own coefficients (1..8)
  int bits = 6;               // linear code bits per coefficient (1..16)
  // Coefficients per term: 1 (one for RGB, a brightness factor with one term) or 3 (one per
  // channel, a colour factor; format 1.5).
  int channels = 3;
  // The refit after training also fits each texel's mean over the images, weighted as this many
  // images' squared errors (cluster/cluster_values.h, fitTexelCoefficients; 0 = least squares).
  double meanWeight = 1;
  // "linear" (codes per column) | "decorrelated" (with channels 3 the colour factor in its
  // principal axes, format 1.11, codec/texel_modulation.h; with one channel linear codes).
  std::string codes = "decorrelated";
};

// How the decoding parts are stored in the .nbtf (the "storage" object of a config). Defaults:
// the compact storage; configs/paper-clustered.json keeps the paper's (float32, raw ids).
struct StorageConfig {
  std::string decoder = "int8";     // "float32" | "half" | "int8" (a half scale per output row)
  std::string latents = "half";     // "float32" | "half"
  std::string ids = "zstd";         // "raw" (smallest integer width) | "zstd"
  std::string directions = "zstd";  // "f64" | "zstd" (format 1.4)
  std::string metadata = "zstd";    // "raw" | "zstd": the metadata and hold-out list (format 1.4)
  // "auto" (as the direction planes: float32 beside a float32 decoder, half otherwise) |
  // "8bit" (a code per value in a float32 range per row and feature, format 1.10)
  std::string clusterPlanes = "auto";
};

// A snapshot of a running training, for callers that log or plot its course.
struct TrainStatus {
  std::int64_t step = 0, totalSteps = 0;  // totalSteps 0: bounded by the time budget only
  double seconds = 0;                     // training time so far (including resumed runs)
  double progress = 0;                    // 0..1, what the schedule and the ETA follow
  double loss = 0;                        // smoothed MSE against the targets (cluster means)
  double rmseEstimate = 0;                // per-texel RMSE estimate: sqrt(loss + within-cluster term)
  double samplesPerSecond = 0;
  double learningRate = 0;
  bool polish = false;                    // encoder frozen, decoder fitting the final latents
};

// The training recipe (configs/*.json, one object per component: "model", "optimizer",
// "training"; see docs/model.md).
struct TrainConfig {
  ModelConfig model;
  ModulationConfig modulation;  // used by the compress pipeline, not by the trainer
  StorageConfig storage;        // likewise
  // ---- optimizer
  std::string optimizer = "adam";  // "sgd" | "adam"
  double learningRate = 2e-3;
  // "inputs": the rate grows with the encoder inputs a step holds beyond the recipe's 32 (x the
  // square root of inputs / 32, at most x kMaxLearningRateScale): stacks with fewer images than
  // imagesPerInput put more inputs in a step, whose averaged gradients carry a larger step
  // (measured: docs/BENCHMARKS.md, *Default amount of training*). "none": the rate as given.
  std::string learningRateScaling = "inputs";
  double momentum = 0;             // sgd only
  // > 0: in the polish phase the stored latents are free parameters, starting from the
  // encoder's outputs, with their own Adam at this rate (a cosine over the phase); 0: they stay
  // the encoder's outputs (docs/model.md, *Free latents*). No effect without a polish phase.
  double latentLearningRate = 0.01;
  // The direction planes' rate (scaled and scheduled as the network's): 0 = learning_rate.
  // Higher than the network's: a grid value is touched only by the samples near it.
  double planeLearningRate = 0.1;
  // ---- training
  int batchSize = 16384;           // decoder samples per step (tiles x imagesPerInput)
  int imagesPerInput = 512;        // images per encoder input in a step (a "tile"); clamped to the training images
  int epochs = 20;                 // one epoch = (encoder inputs) x (training images) decoder samples
  // Bounds on epochs x steps per epoch (0 = no bound; `nbtf compress --epochs E` sets all three
  // to 0). An epoch's size follows k x images, so 20 epochs is 4,000 steps at k = 500 on 6561
  // images but 2 at k = 16 on 81 images. The lower bound is max(minSteps, minStepsPerInput x
  // encoder inputs): the decoder needs a number of optimizer steps whatever the data (minSteps),
  // and more as it has more distinct latents to fit (minStepsPerInput: 24 x k); from k = 500 on
  // (the default k = 1000, per-texel) maxSteps holds them at 12,000, so more clusters cost no
  // more training (at equal steps k = 1000 beats k = 500: docs/model.md).
  int minSteps = 2000;
  int minStepsPerInput = 24;
  int maxSteps = 12000;
  double timeBudgetSeconds = 0;    // 0 = no limit; otherwise training stops when it is spent
  std::string schedule = "cosine"; // "constant" | "cosine" | "step" (x0.1 at 50% and 75%)
  double warmupFraction = 0.02;    // linear learning-rate warm-up, fraction of the run
  // Last fraction of the run: the encoder frozen (eval mode), the decoder (and free latents)
  // fitted to the latents the file stores. Its steps skip the encoder, so a long polish costs
  // less time per step (the measured choice of half the run: docs/model.md, *Free latents*).
  double polishFraction = 0.5;
  // Per-texel free latents (clusters 0, latentLearningRate > 0): blurred over the texture by a
  // Gaussian whose sigma starts at latentBlurSigma texels and halves every latentBlurHalfLife
  // of the polish phase, so they learn what neighbours share before single images' noise
  // (model/autograd/latent_blur.h). 0 = no blur.
  double latentBlurSigma = 0;
  double latentBlurHalfLife = 1.0 / 9;
  double holdoutFraction = 0;      // fraction of (light, view) images kept out of training
  std::uint64_t seed = 1;
  int threads = 0;                 // 0 = threadCount() (all cores unless --threads)
  double checkpointSeconds = 300;  // checkpoint interval (0 = only when stopped)
  std::string checkpointPath;      // "" = no checkpoints
  bool resume = false;             // continue from checkpointPath if it exists
  // Adaptive clustering (pipeline/adaptive.h): continue from checkpointPath, which must exist,
  // although the clusters changed since it was written. The encoder's and decoder's weights,
  // BatchNorm statistics, the Adam moments and step counts and the global step number carry
  // over exactly; only the fingerprint check that ties a checkpoint to one set of clusters is
  // skipped. (Weight shapes do not depend on k: latents are the encoder's outputs.)
  bool warmStart = false;
  bool progress = true;
  // The final exact RMSE over every cluster (or texel) x image: TrainResult::rmseTrain and
  // rmseHoldout. The compressor turns it off when it measures the stored file instead (its
  // rounded parts and refit coefficients): then both are -1, and a time budget keeps no time
  // for it.
  bool finalEvaluation = true;
  // ---- backend (docs/model.md, *Training backends*)
  // "fused": the hand-written CPU kernels (decoder pass, conv + pool, BatchNorm, Adam), fast
  // and checked against torch in tests. "torch": stock libtorch modules, autograd and
  // torch::optim; the place to try a model change before writing its gradients by hand.
  std::string backend = "fused";
  // "float" | "bf16" | "auto": the fused decoder pass's hidden-layer products in float, or
  // with bfloat16 operands and float sums (model/kernels/dense_kernels.h): about twice the
  // multiply-adds per cycle on CPUs with AVX-512 BF16, the same bits (slower) elsewhere.
  // "auto" (the default): bf16 where the CPU has the instruction, else float.
  std::string products = "auto";
  // "cpu" | "cuda". cuda needs the torch backend and a libtorch built with CUDA (Debian's is
  // CPU-only: a clear error there).
  std::string device = "cpu";
  // ---- data-parallel training over processes (not in config files: `nbtf compress
  // --world-size N --rank R --master HOST:PORT`; model/distributed/distributed.h)
  DistributedConfig distributed;
  // The built-in config the recipe came from (`--config compact`; "" = a file or the compiled-in
  // default): the file's metadata records it as "config_name".
  std::string builtInConfig;
  // ---- run control (not in config files)
  std::atomic<bool>* stopFlag = nullptr;  // set (e.g. by SIGINT) -> checkpoint and return, interrupted
  std::int64_t stopAtStep = 0;            // > 0: behave as if stopped once this many steps are done
  double stopAtSeconds = 0;               // > 0: the same once the run's training clock (resumed runs included) reaches it
  std::function<void(const TrainStatus&)> monitor;  // called after every step (keep it cheap)
};

// training.products as this CPU runs it: "bf16" or "float" ("auto": bf16 where the CPU has
// AVX-512 BF16 and the backend is the fused one).
std::string resolvedProducts(const TrainConfig& config);

// Loads a config file; unknown keys and wrong types are errors naming the file and key.
// Keys that are absent keep the defaults above.
TrainConfig loadTrainConfig(const std::string& path);
// Throws nbtf::Error naming `source` and the key when a value is out of range.
void validateTrainConfig(const TrainConfig& config, const std::string& source);
// The recipe as a JSON object in the config-file format (reloadable by loadTrainConfig), as
// a file records it: without run-control and path keys, which do not change the result.
std::string trainConfigJson(const TrainConfig& config);

// The step geometry of a run: decoder samples per step and per epoch, steps per epoch, and
// the planned optimizer steps: epochs x steps per epoch, at least max(min_steps,
// min_steps_per_input x encoder inputs), at most max_steps (0 when training is bounded by the
// time budget only).
struct TrainPlan {
  std::int64_t batch = 0, stepsPerEpoch = 0, totalSteps = 0;
  int perTile = 0, tiles = 0;
  double learningRateScale = 1;  // optimizer.learning_rate_scaling applied to this geometry
};
// The recipe's encoder inputs per step (16,384 samples / 512 images) and the largest factor
// the "inputs" scaling gives (its measurement: docs/model.md, *How much training the default does*).
constexpr double kReferenceInputsPerStep = 32;
constexpr double kMaxLearningRateScale = 2.5;
TrainPlan planTraining(const TrainConfig& config, std::int64_t encoderInputs, int trainImages);

}  // namespace nbtf
