// The training loop: sample a step (a few encoder inputs x many images each), run the
// encoder once per distinct input with autograd, the decoder by hand (decoder_backprop.h),
// step the optimizer; checkpoint, resume, and finally the exact per-texel RMSE.
#include "model/trainer.h"

#include "model/torch_logging.h"

#include <ATen/Parallel.h>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>

#include "model/decoder_backprop.h"
#include "model/distributed_group.h"
#include "model/fused_adam.h"
#include "model/torch_modules.h"
#include "model/train_checkpoint.h"
#include "model/train_eval.h"
#include "model/training_set.h"
#include "util/error.h"
#include "util/parallel.h"
#include "util/progress.h"
#include "util/timer.h"

namespace nbtf {
namespace {

using detail::Decoder;
using detail::DecoderBackprop;
using detail::Encoder;
using detail::exportPlanes;


// Encoder input tensor [rows.size(), 3, N] from the standardized matrix, whose row r holds
// column 3 * image + channel (interleaved): element [j, c, i] = X(rows[j], 3 i + c).
torch::Tensor gatherEncoderInputs(const MatrixXfCol& x, const int* rows, std::int64_t count) {
  const std::int64_t images = x.cols() / 3;
  torch::Tensor out = torch::empty({count, 3, images});
  float* dst = out.data_ptr<float>();
  const float* src = x.data();
  const std::int64_t stride = x.rows();
  at::parallel_for(0, images, 256, [&](std::int64_t begin, std::int64_t end) {
    for (std::int64_t i = begin; i < end; ++i)
      for (int c = 0; c < 3; ++c) {
        const float* col = src + (3 * i + c) * stride;
        for (std::int64_t j = 0; j < count; ++j) dst[(j * 3 + c) * images + i] = col[rows[j]];
      }
  });
  return out;
}

// The encoder inputs of a training step. X is column-major, so a step's few rows are
// scattered over all 3N columns (a cache miss per value); when X is small enough (always in
// the clustered mode: k representatives) a row-major [rows, 3, N] copy is made once and a
// step's inputs are whole-row copies.
class EncoderInputSource {
 public:
  explicit EncoderInputSource(const MatrixXfCol& x) : x_(x) {
    constexpr std::int64_t kMaxCopyFloats = std::int64_t{64} << 20;  // 256 MB
    if (x.size() > kMaxCopyFloats) return;
    std::vector<int> all(static_cast<std::size_t>(x.rows()));
    for (std::size_t r = 0; r < all.size(); ++r) all[r] = static_cast<int>(r);
    planar_ = gatherEncoderInputs(x, all.data(), x.rows());
  }
  torch::Tensor rows(const int* rows, std::int64_t count) const {
    if (!planar_.defined()) return gatherEncoderInputs(x_, rows, count);
    // Whole-row copies on all threads (index_select copied on one).
    torch::Tensor out = torch::empty({count, planar_.size(1), planar_.size(2)});
    const std::int64_t rowFloats = planar_.size(1) * planar_.size(2);
    const float* src = planar_.data_ptr<float>();
    float* dst = out.data_ptr<float>();
    at::parallel_for(0, count, 8, [&](std::int64_t begin, std::int64_t end) {
      for (std::int64_t j = begin; j < end; ++j)
        std::memcpy(dst + j * rowFloats, src + rows[j] * rowFloats, rowFloats * sizeof(float));
    });
    return out;
  }

 private:
  const MatrixXfCol& x_;
  torch::Tensor planar_;
};

// Latents of every encoder input in eval mode (BatchNorm running statistics), in chunks
// so the first conv block's activations stay small; on the CPU. `stock`: through the stock
// torch modules (the torch backend), on the encoder's device.
torch::Tensor encodeAll(Encoder& encoder, const MatrixXfCol& x, bool stock = false,
                        const torch::Device& device = torch::kCPU) {
  torch::NoGradGuard noGrad;
  encoder->eval();
  const std::int64_t rows = x.rows();
  std::vector<torch::Tensor> parts;
  std::vector<int> index;
  const std::int64_t chunk = 128;
  for (std::int64_t r0 = 0; r0 < rows; r0 += chunk) {
    std::int64_t n = std::min(chunk, rows - r0);
    index.resize(n);
    for (std::int64_t j = 0; j < n; ++j) index[j] = static_cast<int>(r0 + j);
    torch::Tensor in = gatherEncoderInputs(x, index.data(), n);
    parts.push_back(stock ? encoder->forwardStock(in.to(device)).to(torch::kCPU) : encoder->forward(in));
  }
  return torch::cat(parts, 0).contiguous();
}

// The device of the torch backend; a clear error where this libtorch cannot run there.
torch::Device trainingDevice(const TrainConfig& config) {
  if (config.device != "cuda") return torch::kCPU;
  if (!torch::cuda::is_available())
    throw Error("training.device \"cuda\": this libtorch has no usable CUDA device (Debian's libtorch is built "
                "for the CPU only); use \"cpu\"");
  return torch::Device(torch::kCUDA, 0);
}

// The forward and backward pass of the torch backend: stock modules and autograd (the
// optimizer, torch::optim, steps after it). z: [tiles, latent]
// (from the encoder, with its graph, or the frozen polish latents); dirs and targets on the
// CPU. Gradients are reset to undefined, not zero, so parameters outside the graph (the
// frozen encoder while polishing) are not moved by the optimizer's momentum.
// With trailingInputs > 0 it also stores dLoss/d(input) of the last trailingInputs direction
// inputs of every row in trailingGradient (the direction planes' features).
double stockTrainStep(Decoder& decoder, const std::vector<torch::Tensor>& params, const torch::Tensor& z,
                      const torch::Tensor& dirs, const torch::Tensor& targets, int perTile, const torch::Device& device,
                      int trailingInputs, std::vector<float>& trailingGradient) {
  for (const torch::Tensor& p : params) p.mutable_grad() = torch::Tensor();
  torch::Tensor d = dirs.to(device);
  if (trailingInputs > 0) d = d.detach().requires_grad_(true);
  torch::Tensor inputs = torch::cat({z.repeat_interleave(perTile, 0), d}, 1);
  torch::Tensor loss = torch::mse_loss(decoder->forward(inputs), targets.to(device));
  loss.backward();
  if (trailingInputs > 0) {
    torch::Tensor g = d.grad().narrow(1, d.size(1) - trailingInputs, trailingInputs).to(torch::kCPU).contiguous();
    trailingGradient.assign(g.data_ptr<float>(), g.data_ptr<float>() + g.numel());
  }
  return loss.item<double>();
}

// Learning-rate factor at training progress p in [0, 1].
double scheduleFactor(const TrainConfig& c, double p) {
  double f = 1;
  if (c.warmupFraction > 0 && p < c.warmupFraction) f = std::max(p, 1e-3) / c.warmupFraction;
  double q = c.warmupFraction < 1 ? (p - c.warmupFraction) / (1 - c.warmupFraction) : 1;
  q = std::min(1.0, std::max(0.0, q));
  if (c.schedule == "cosine") f *= 0.5 * (1 + std::cos(M_PI * q));
  else if (c.schedule == "step") f *= q < 0.5 ? 1.0 : q < 0.75 ? 0.1 : 0.01;
  return f;
}

// The free latents' learning-rate factor: a cosine over the polish phase (p from
// 1 - polishFraction to 1), so they move most while the decoder is still adapting to them.
double polishScheduleFactor(const TrainConfig& c, double p) {
  const double q = std::min(1.0, std::max(0.0, (p - (1 - c.polishFraction)) / c.polishFraction));
  return 0.5 * (1 + std::cos(M_PI * q));
}

// One polish step's forward and backward pass over the polish latents of the step's tiles
// (`decoderStep` returns the loss and, in the fused backend, dL/dz in dz). When the latents are
// free their gradient is the tiles' dz summed per encoder input (autograd's in the torch backend).
template <typename DecoderStep>
double polishStep(PolishLatents& polish, const torch::Tensor& tileGroup, DecoderStep decoderStep, bool stock,
                  torch::Tensor& dz) {
  if (!polish.free()) return decoderStep(polish.values.index_select(0, tileGroup));
  polish.values.mutable_grad() = torch::Tensor();
  if (stock) {
    polish.values.requires_grad_(true);
    const double loss = decoderStep(polish.values.index_select(0, tileGroup));
    polish.values.requires_grad_(false);
    return loss;
  }
  const double loss = decoderStep(polish.values.index_select(0, tileGroup));
  polish.values.mutable_grad() = torch::zeros_like(polish.values).index_add_(0, tileGroup, dz);
  return loss;
}

// Every group's rate: lr for the network (group 0), lr x `secondFactor` for the second group
// (the direction planes, when they are there).
void setLearningRate(torch::optim::Optimizer& opt, double lr, double secondFactor = 1) {
  auto& groups = opt.param_groups();
  for (std::size_t g = 0; g < groups.size(); ++g) groups[g].options().set_lr(g == 0 ? lr : lr * secondFactor);
}

// The network's parameters in one group and, when defined, the direction planes in a second
// (optimizer.plane_learning_rate gives them a rate of their own).
std::unique_ptr<torch::optim::Optimizer> makeOptimizer(const TrainConfig& c, std::vector<torch::Tensor> params,
                                                       const torch::Tensor& planes) {
  const bool sgd = c.optimizer == "sgd";
  auto options = [&]() -> std::unique_ptr<torch::optim::OptimizerOptions> {
    if (sgd) return std::make_unique<torch::optim::SGDOptions>(torch::optim::SGDOptions(c.learningRate).momentum(c.momentum));
    return std::make_unique<torch::optim::AdamOptions>(c.learningRate);
  };
  std::vector<torch::optim::OptimizerParamGroup> groups;
  std::vector<torch::Tensor> network;
  for (const torch::Tensor& p : params)
    if (!planes.defined() || !p.is_same(planes)) network.push_back(p);
  groups.emplace_back(network, options());
  if (planes.defined()) groups.emplace_back(std::vector<torch::Tensor>{planes}, options());
  if (sgd)
    return std::make_unique<torch::optim::SGD>(std::move(groups), torch::optim::SGDOptions(c.learningRate).momentum(c.momentum));
  return std::make_unique<torch::optim::Adam>(std::move(groups), torch::optim::AdamOptions(c.learningRate));
}

std::vector<std::uint8_t> serializeModule(torch::nn::Module& module) {
  torch::serialize::OutputArchive archive;
  module.save(archive);
  std::vector<std::uint8_t> bytes;
  archive.save_to([&](const void* data, std::size_t size) {
    const auto* p = static_cast<const std::uint8_t*>(data);
    bytes.insert(bytes.end(), p, p + size);
    return size;
  });
  return bytes;
}

// `epoch` is the one being run, 1-based (the last step's epoch stays the last one).
std::string formatStatus(double loss, double rmse, double samplesPerSecond, double gflops, std::int64_t epoch,
                         std::int64_t epochs, bool polish) {
  char buf[192];
  if (epochs > 0) epoch = std::min(epoch, epochs);
  const std::string ep = epochs > 0 ? std::to_string(epoch) + "/" + std::to_string(epochs) : std::to_string(epoch);
  std::snprintf(buf, sizeof buf, "epoch %s  loss %.3e  rmse~ %.4f  %.0fk smp/s  %.1f GF/s%s", ep.c_str(), loss, rmse,
                samplesPerSecond / 1e3, gflops, polish ? "  (decoder polish)" : "");
  return buf;
}

}  // namespace

TrainResult trainModel(const TrainInputs& inputs, const TrainConfig& config) {
  detail::quietTorchLogging();
  validateTrainConfig(config, "training config");
#if defined(__GLIBC__)
  // A step allocates and frees the same few-megabyte activation tensors every time. glibc
  // serves blocks that large with mmap and unmaps them on free, so every step paid fresh
  // page faults (a few percent of its time); from the heap, the pages are reused.
  mallopt(M_MMAP_THRESHOLD, 64 << 20);
  mallopt(M_TRIM_THRESHOLD, 128 << 20);
#endif
  const auto callStart = Clock::now();
  const int threads = config.threads > 0 ? config.threads : threadCount();
  torch::set_num_threads(threads);

  TrainingSet set(inputs, config.holdoutFraction, config.seed, config.progress, config.model.directionInputs,
                  config.model.planeFeatures);
  const MatrixXfCol& x = *inputs.encoderInputs;
  const EncoderInputSource inputSource(x);
  const int latentDim = config.model.latentDim;

  // ---- Model and optimizer, initialized from the seed.
  torch::manual_seed(config.seed);
  Encoder encoder(set.images(), config.model);
  Decoder decoder(config.model);
  const bool stock = config.backend == "torch";
  const torch::Device device = trainingDevice(config);
  if (!device.is_cpu()) encoder->to(device), decoder->to(device);
  std::vector<torch::Tensor> params = encoder->parameters();
  for (auto& p : decoder->parameters()) params.push_back(p);
  auto optimizer = makeOptimizer(config, params, decoder->planes);  // its rates are set before every step
  const double planeRateFactor = config.planeLearningRate > 0 ? config.planeLearningRate / config.learningRate : 1;
  DecoderBackprop backprop(decoder, latentDim);
  // Learned direction planes: their features are the last direction inputs, sampled anew
  // after every step that moved them; their gradient comes from the decoder's input gradient.
  const int planeInputs = set.planeInputs();
  backprop.setTrailingInputGradient(planeInputs);
  std::vector<float> stockInputGradient;
  DirectionPlanes stepPlanes;  // the planes as this step samples them
  const Mlp decoderMlpShape = decoderShape(config.model);
  const double flopsPerSample = decoderMlpShape.flopsPerSample();

  // ---- Step geometry: `tiles` encoder inputs x `perTile` images = one decoder batch.
  const int trainImages = static_cast<int>(set.trainImages().size());
  const TrainPlan geometry = planTraining(config, set.groups(), trainImages);
  const int perTile = geometry.perTile, tiles = geometry.tiles;
  const std::int64_t batch = geometry.batch, stepsPerEpoch = geometry.stepsPerEpoch;
  const std::int64_t totalSteps = geometry.totalSteps;  // 0: time budget only

  // ---- Data-parallel: rendezvous, and this rank's share of every step's tiles.
  std::unique_ptr<detail::DistributedGroup> group;
  int shareBegin = 0, shareEnd = tiles;
  if (config.distributed.enabled()) {
    if (config.timeBudgetSeconds > 0)
      throw Error("--time-budget cannot be used with --world-size > 1 (ranks must run the same steps); use --epochs");
    if (config.resume) throw Error("--resume cannot be used with --world-size > 1");
    if (tiles < config.distributed.worldSize)
      throw Error("--world-size " + std::to_string(config.distributed.worldSize) + " exceeds the " +
                  std::to_string(tiles) + " encoder inputs of a step: every rank needs at least one");
    tileShare(tiles, config.distributed.rank, config.distributed.worldSize, shareBegin, shareEnd);
    // The training set follows from the settings the pipeline listed, but it is what the
    // collectives' buffer sizes come from: checked too, so no rank reaches Gloo with others.
    DistributedConfig dist = config.distributed;
    std::string holdout;
    for (int i : set.holdoutImages()) holdout += (holdout.empty() ? "" : ",") + std::to_string(i);
    dist.mustAgree.push_back({"training set: encoder inputs", std::to_string(set.groups())});
    dist.mustAgree.push_back({"training set: images", std::to_string(set.images())});
    dist.mustAgree.push_back({"training set: texels", std::to_string(set.texels())});
    dist.mustAgree.push_back({"training set: held-out images", holdout.empty() ? "none" : holdout});
    dist.mustAgree.push_back({"training set: per-texel modulation (checksum)", std::to_string(set.texelCoefficientHash())});
    group = std::make_unique<detail::DistributedGroup>(dist);
  }
  const bool worker = group && group->rank() != 0;

  // ---- Resume.
  CheckpointMeta meta;
  meta.fingerprint = checkpointFingerprint(config, set);
  meta.totalSteps = totalSteps;
  std::int64_t step = 0;
  double priorSeconds = 0, emaLoss = -1;
  TrainResult result;
  PolishLatents polish;
  if (config.warmStart && !checkpointExists(config.checkpointPath))
    throw Error("training: a warm start needs the previous stage's checkpoint, \"" + config.checkpointPath +
                "\" does not exist");
  if ((config.resume || config.warmStart) && checkpointExists(config.checkpointPath)) {
    CheckpointMeta saved = loadCheckpoint(config.checkpointPath, meta.fingerprint, *encoder, *decoder, *optimizer,
                                          polish, config.latentLearningRate, !config.warmStart);
    if (config.resume && !config.warmStart && saved.totalSteps != totalSteps) {
      auto plan = [](std::int64_t steps) {
        return steps > 0 ? std::to_string(steps) + " steps" : std::string("a time budget only");
      };
      throw fileError(config.checkpointPath,
                      "checkpoint of a run planned for " + plan(saved.totalSteps) + ", this run plans " +
                          plan(totalSteps) + " (--epochs or the config's step bounds changed); the learning-rate "
                          "schedule spans the whole run, so resume with the options of the interrupted run, or "
                          "start over without --resume");
    }
    step = saved.step;
    priorSeconds = saved.elapsedSeconds;
    emaLoss = saved.emaLoss;
    result.resumedFromStep = step;
  }

  // ---- Per-step buffers.
  StepPlan plan;
  if (3 * config.model.outputTerms != set.outputs())
    throw Error("training: the decoder gives " + std::to_string(3 * config.model.outputTerms) + " outputs but the " +
                "targets have " + std::to_string(set.outputs()) + " (model.outputTerms must equal the modulation terms)");
  const int outputs = set.outputs();
  // The loss is a mean over the decoder's outputs; per texel and channel it counts terms times.
  const double lossToTexelMse = outputs / 3.0;
  const int dirWidth = set.directionWidth();
  torch::Tensor dirs = torch::empty({batch, dirWidth}), targets = torch::empty({batch, outputs}), dz;
  torch::Tensor tileSlot = torch::empty({tiles}, torch::kLong), tileGroup = torch::empty({tiles}, torch::kLong);
  double withinTrain = 0;
  for (int i : set.trainImages()) withinTrain += set.withinSse(i);
  withinTrain /= static_cast<double>(set.texels()) * trainImages * 3;

  // The bar counts optimizer steps, or whole seconds of the budget when only a budget bounds
  // the run: units a user can compare with the summary.
  const bool barInSeconds = totalSteps == 0;
  const std::int64_t totalEpochs = totalSteps > 0 ? (totalSteps + stepsPerEpoch - 1) / stepsPerEpoch : 0;
  Progress bar(barInSeconds ? "train (s)" : "train (steps)",
               static_cast<std::size_t>(barInSeconds ? std::ceil(config.timeBudgetSeconds) : totalSteps),
               config.progress);
  std::size_t shown = barInSeconds ? static_cast<std::size_t>(priorSeconds) : static_cast<std::size_t>(step);
  bar.advance(shown);
  const auto loopStart = Clock::now();
  auto lastCheckpoint = loopStart, lastStatus = loopStart;
  const std::int64_t firstStep = step;
  // The time budget covers the whole call: the set-up above, the loop (over resumed runs too)
  // and the final exact evaluation, whose cost is estimated from the measured step rate
  // (a forward pass over every group x image costs about a third of a training sample).
  auto elapsedTotal = [&] { return priorSeconds + secondsSince(callStart); };
  const double evalSamples = static_cast<double>(set.groups()) * set.images();
  auto finalEvalSeconds = [&] {
    const double loopSeconds = secondsSince(loopStart);
    if (step == firstStep || loopSeconds < 0.5) return 0.0;
    const double sps = (step - firstStep) * static_cast<double>(batch) / loopSeconds;
    return evalSamples / (3 * sps);
  };
  auto progressOf = [&](std::int64_t s, double elapsed) {
    double p = 0;
    if (totalSteps > 0) p = static_cast<double>(s) / totalSteps;
    if (config.timeBudgetSeconds > 0) p = std::max(p, (elapsed + finalEvalSeconds()) / config.timeBudgetSeconds);
    return std::min(1.0, p);
  };
  auto writeCheckpointNow = [&] {
    if (config.checkpointPath.empty() || worker) return;  // rank 0 checkpoints for all
    meta.step = step;
    meta.elapsedSeconds = elapsedTotal();
    meta.emaLoss = emaLoss;
    saveCheckpoint(config.checkpointPath, meta, *encoder, *decoder, *optimizer, polish);
    lastCheckpoint = Clock::now();
  };

  encoder->train();
  while (true) {
    const double elapsed = elapsedTotal();
    if (totalSteps > 0 && step >= totalSteps) break;
    if (config.timeBudgetSeconds > 0 && elapsed + finalEvalSeconds() >= config.timeBudgetSeconds) break;
    if ((config.stopFlag && config.stopFlag->load()) || (config.stopAtStep > 0 && step >= config.stopAtStep)) {
      result.interrupted = true;
      writeCheckpointNow();
      break;
    }
    const double p = progressOf(step, elapsed);
    const bool polishing = config.polishFraction > 0 && p >= 1 - config.polishFraction;
    setLearningRate(*optimizer, config.learningRate * geometry.learningRateScale * scheduleFactor(config, p),
                    planeRateFactor);

    // Samples: which groups and images, then their directions and targets.
    auto tPhase = Clock::now();
    auto lap = [&](double& slot) {
      auto now = Clock::now();
      slot += std::chrono::duration<double>(now - tPhase).count();
      tPhase = now;
    };
    planStep(set, config.seed, step, tiles, perTile, plan);
    if (planeInputs > 0) {
      stepPlanes = exportPlanes(decoder);
      set.setPlaneFeatures(stepPlanes);
    }
    // This rank's share of the step's tiles (all of them in one process). The encoder still
    // runs on every distinct input of the step, so its BatchNorm sees the same batch on every
    // rank as in one process; only the decoder's rows (the cost) are split.
    const int stepTiles = shareEnd - shareBegin;
    {
      float* d = dirs.data_ptr<float>();
      float* y = targets.data_ptr<float>();
      const std::vector<float>& allDirs = set.directions();
      at::parallel_for(0, stepTiles, 1, [&](std::int64_t begin, std::int64_t end) {
        for (std::int64_t t = begin; t < end; ++t) {
          const int* img = &plan.images[(shareBegin + t) * perTile];
          set.targets(plan.tileGroup[shareBegin + t], img, perTile, y + t * perTile * outputs);
          for (int s = 0; s < perTile; ++s)
            std::memcpy(d + (t * perTile + s) * dirWidth, &allDirs[static_cast<std::size_t>(img[s]) * dirWidth],
                        dirWidth * sizeof(float));
        }
      });
    }
    for (int t = 0; t < stepTiles; ++t) {
      tileSlot.data_ptr<std::int64_t>()[t] = plan.tileSlot[shareBegin + t];
      tileGroup.data_ptr<std::int64_t>()[t] = plan.tileGroup[shareBegin + t];
    }
    // Views of the step's rows (all of them unless this rank trains a share).
    const std::int64_t stepRows = static_cast<std::int64_t>(stepTiles) * perTile;
    const torch::Tensor stepDirs = dirs.narrow(0, 0, stepRows), stepTargets = targets.narrow(0, 0, stepRows);
    const torch::Tensor stepTileSlot = tileSlot.narrow(0, 0, stepTiles), stepTileGroup = tileGroup.narrow(0, 0, stepTiles);

    double loss;
    TrainResult::Profile& prof = result.profile;
    lap(prof.sampling);
    if (!polishing) {
      torch::Tensor in = inputSource.rows(plan.distinctGroups.data(),
                                             static_cast<std::int64_t>(plan.distinctGroups.size()));
      if (stock) {
        // Autograd through encoder and decoder; the whole step is timed as the decoder's.
        torch::Tensor z = encoder->forwardStock(in.to(device)).index_select(0, stepTileSlot.to(device));
        loss = stockTrainStep(decoder, params, z, stepDirs, stepTargets, perTile, device, planeInputs,
                              stockInputGradient);
        lap(prof.decoder);
      } else {
        for (auto& p : encoder->parameters()) p.mutable_grad() = torch::Tensor();
        torch::Tensor z = encoder->forward(in).index_select(0, stepTileSlot);
        lap(prof.encoder);
        loss = backprop.trainStep(z.detach(), stepDirs, stepTargets, perTile, dz);
        lap(prof.decoder);
        z.backward(dz);
        lap(prof.encoder);
      }
    } else {
      if (!polish.values.defined()) {
        // Freeze the encoder: from here on the decoder fits the latents that will be stored
        // (and, when they are free, they fit the decoder).
        polish.start(encodeAll(encoder, x, stock, device), config.latentLearningRate);
        for (auto& p : encoder->parameters()) p.mutable_grad() = torch::Tensor();
      }
      lap(prof.encoder);
      loss = polishStep(polish, stepTileGroup, [&](const torch::Tensor& z) {
        return stock ? stockTrainStep(decoder, params, z.to(device), stepDirs, stepTargets, perTile, device, planeInputs,
                                      stockInputGradient)
                     : backprop.trainStep(z, stepDirs, stepTargets, perTile, dz);
      }, stock, dz);
      if (polish.free())
        setLearningRate(*polish.optimizer, config.latentLearningRate * polishScheduleFactor(config, p));
      lap(prof.decoder);
    }
    if (planeInputs > 0) {
      torch::Tensor gradient = torch::zeros_like(decoder->planes);
      set.addPlaneGradient(stepPlanes, &plan.images[static_cast<std::size_t>(shareBegin) * perTile],
                           stock ? stockInputGradient.data() : backprop.inputGradient().data(), stepRows,
                           gradient.data_ptr<float>());
      decoder->planes.mutable_grad() = gradient;
      lap(prof.decoder);
    }
    if (group) {
      // The whole step's gradient and loss: each rank's (a mean over its rows) weighted by its
      // share of the rows, summed over the ranks. Every rank then takes the same step.
      const double weight = static_cast<double>(stepTiles) / tiles;
      std::vector<torch::Tensor> reduced = params;
      if (polish.free()) reduced.push_back(polish.values);
      for (const torch::Tensor& p : reduced)
        if (p.grad().defined()) p.grad().mul_(weight);
      loss = group->allReduceGradients(reduced, loss * weight);
    }
    if (!std::isfinite(loss))
      throw Error("training diverged at step " + std::to_string(step) +
                  " (loss is not finite); lower optimizer.learning_rate");
    if (stock) {
      optimizer->step();
    } else if (auto* adam = dynamic_cast<torch::optim::Adam*>(optimizer.get())) {
      detail::fusedAdamStep(*adam);
    } else {
      optimizer->step();
    }
    if (polishing && polish.free()) detail::fusedAdamStep(*polish.optimizer);
    lap(prof.optimizer);
    ++step;
    emaLoss = emaLoss < 0 ? loss : 0.98 * emaLoss + 0.02 * loss;

    // Progress, status line, periodic checkpoint.
    const double now = elapsedTotal();
    const std::size_t done = barInSeconds ? static_cast<std::size_t>(now) : static_cast<std::size_t>(step);
    if (done > shown) bar.advance(done - shown), shown = done;
    const double sps = (step - firstStep) * static_cast<double>(batch) / std::max(1e-9, secondsSince(loopStart));
    if (config.monitor) {
      TrainStatus st;
      st.step = step, st.totalSteps = totalSteps, st.seconds = now, st.progress = progressOf(step, now);
      st.loss = emaLoss, st.rmseEstimate = std::sqrt(emaLoss * lossToTexelMse + withinTrain), st.samplesPerSecond = sps;
      st.learningRate = config.learningRate * geometry.learningRateScale * scheduleFactor(config, p), st.polish = polishing;
      config.monitor(st);
    }
    if (secondsSince(lastStatus) > 0.5) {
      bar.setStatus(formatStatus(emaLoss, std::sqrt(emaLoss * lossToTexelMse + withinTrain), sps, sps * 3 * flopsPerSample / 1e9,
                                 step / stepsPerEpoch + 1, totalEpochs, polishing));
      lastStatus = Clock::now();
    }
    if (config.checkpointSeconds > 0 && secondsSince(lastCheckpoint) >= config.checkpointSeconds) writeCheckpointNow();
  }
  result.trainSeconds = secondsSince(loopStart);
  bar.finish();
  if (group && group->calls() > 0) {
    result.allReduceBytesPerStep = group->bytesReduced() / group->calls();
    result.allReduceSecondsPerStep = group->secondsInCollectives() / group->calls();
  }
  result.steps = step;
  result.epochsRun = static_cast<int>(step / stepsPerEpoch);
  result.finalLoss = std::max(0.0, emaLoss);
  result.encoderBlocks = encoder->blocks;
  result.samplesPerSecond =
      result.trainSeconds > 0 ? (step - firstStep) * static_cast<double>(batch) / result.trainSeconds : 0;
  if (worker) {
    // Rank 0 exports, evaluates and writes; this rank's part is done.
    result.worker = true;
    result.rmseTrain = result.rmseHoldout = -1;
    result.seconds = secondsSince(callStart);
    return result;
  }

  // ---- Export: eval-mode latents, the decoder as an Mlp, the encoder's state.
  result.decoderGflops = result.samplesPerSecond * 3 * flopsPerSample / 1e9;
  result.holdoutImages = set.holdoutImages();
  // The polish phase's latents are the ones the decoder was fitted to last (the encoder's
  // outputs, moved when free); without a polish phase, the encoder's.
  torch::Tensor latents = polish.values.defined() ? polish.values.detach() : encodeAll(encoder, x, stock, device);
  if (!device.is_cpu()) encoder->to(torch::kCPU), decoder->to(torch::kCPU);  // export and evaluate on the CPU
  result.latentRows = set.groups();
  result.latents.assign(latents.data_ptr<float>(), latents.data_ptr<float>() + latents.numel());
  result.decoder = detail::exportDecoder(decoder);
  result.planes = exportPlanes(decoder);
  set.setPlaneFeatures(result.planes);  // the final planes, for the evaluation below
  result.encoderState = serializeModule(*encoder);
  if (!config.checkpointPath.empty() && !result.interrupted) writeCheckpointNow();

  // ---- Exact RMSE over texels x images x channels (eq. 10), from per-cluster sums.
  if (result.interrupted) {
    result.rmseTrain = result.rmseHoldout = -1;
  } else {
    detail::RmsError rmse = detail::evaluateRmse(set, backprop, latents, config.progress);
    result.rmseTrain = rmse.train;
    result.rmseHoldout = rmse.holdout;
    if (!set.perTexel()) result.rmseFloor = std::sqrt(withinTrain);
  }
  result.seconds = secondsSince(callStart);
  return result;
}

}  // namespace nbtf
