// The training loop: sample a step (a few encoder inputs x many images each), run the
// encoder once per distinct input with autograd, the decoder by hand (decoder_backprop.h),
// step the optimizer; checkpoint, resume, and finally the exact per-texel RMSE.
#include "model/trainer.h"

#include "model/autograd/torch_logging.h"

#include <ATen/Parallel.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>

#include "model/autograd/decoder_backprop.h"
#include "model/distributed/distributed_group.h"
#include "model/autograd/fused_adam.h"
#include "model/autograd/latent_blur.h"
#include "model/autograd/torch_modules.h"
#include "model/train_checkpoint.h"
#include "model/train_eval.h"
#include "model/training_set.h"
#include "util/error.h"
#include "util/memory.h"
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

// The texture the per-texel latents lie on, and the blur they are seen through now
// (sigma 0: none; clustered latents have no texture).
struct LatentImage {
  int width = 0, height = 0;
  double sigma = 0;
  torch::Tensor view(const torch::Tensor& values) const {
    return detail::blurLatentImage(values, width, height, sigma);
  }
};

// One polish step's forward and backward pass over the polish latents of the step's tiles
// (`decoderStep` returns the loss and, in the fused backend, dL/dz in dz). When the latents are
// free their gradient is the tiles' dz summed per encoder input (autograd's in the torch backend),
// taken back through the blur when there is one.
template <typename DecoderStep>
double polishStep(PolishLatents& polish, const torch::Tensor& tileGroup, DecoderStep decoderStep, bool stock,
                  torch::Tensor& dz, const LatentImage& image) {
  if (!polish.free()) return decoderStep(polish.values.index_select(0, tileGroup));
  polish.values.mutable_grad() = torch::Tensor();
  if (stock) {
    polish.values.requires_grad_(true);
    const double loss = decoderStep(image.view(polish.values).index_select(0, tileGroup));
    polish.values.requires_grad_(false);
    return loss;
  }
  if (image.sigma > 0) {
    torch::Tensor values = polish.values.detach().requires_grad_(true);
    torch::Tensor seen = image.view(values);
    const double loss = decoderStep(seen.detach().index_select(0, tileGroup));
    seen.backward(torch::zeros_like(seen).index_add_(0, tileGroup, dz));
    polish.values.mutable_grad() = values.grad();
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
                                                       const torch::Tensor& planes,
                                                       const torch::Tensor& clusterPlanes = torch::Tensor()) {
  const bool sgd = c.optimizer == "sgd";
  auto options = [&]() -> std::unique_ptr<torch::optim::OptimizerOptions> {
    if (sgd) return std::make_unique<torch::optim::SGDOptions>(torch::optim::SGDOptions(c.learningRate).momentum(c.momentum));
    return std::make_unique<torch::optim::AdamOptions>(c.learningRate);
  };
  std::vector<torch::optim::OptimizerParamGroup> groups;
  std::vector<torch::Tensor> network;
  for (const torch::Tensor& p : params)
    if (!(planes.defined() && p.is_same(planes)) && !(clusterPlanes.defined() && p.is_same(clusterPlanes)))
      network.push_back(p);
  groups.emplace_back(network, options());
  std::vector<torch::Tensor> grids;
  if (planes.defined()) grids.push_back(planes);
  if (clusterPlanes.defined()) grids.push_back(clusterPlanes);
  if (!grids.empty()) groups.emplace_back(grids, options());
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

// One training run (trainModel): the data, the model, its optimizer and the run's clock,
// stepped until the plan or the budget ends. Set-up in the constructor; resume() picks up a
// checkpoint; step() is one optimizer step (sample, forward and backward, reduce over ranks,
// update, report); finish() exports the model and measures its exact RMSE.
class TrainingRun {
 public:
  TrainingRun(const TrainInputs& inputs, const TrainConfig& config, Clock::time_point callStart)
      : config_(config),
        callStart_(callStart),
        set_(inputs, config.holdoutFraction, config.seed, config.progress, config.model.directionInputs,
             config.model.planeFeatures, config.model.planeResolution, config.model.clusterPlaneFeatures,
             config.model.clusterPlaneResolution),
        x_(*inputs.encoderInputs),
        inputSource_(x_),
        encoder_(nullptr),
        decoder_(nullptr) {
    if (config_.latentBlurSigma > 0) checkLatentBlur(inputs);
    buildModel();
    geometry_ = planTraining(config_, set_.groups(), static_cast<int>(set_.trainImages().size()));
    tileShare_ = {0, geometry_.tiles};
    if (config_.distributed.enabled()) joinGroup();
  }

  void resume();
  // Checks the targets against the decoder, allocates the step's buffers, starts the clock
  // and the progress bar.
  void startLoop();
  // False once the plan is done, the budget spent, or a stop was asked for (then checkpointed).
  bool wantsStep();
  void step();
  TrainResult finish();

 private:
  void buildModel();
  void checkLatentBlur(const TrainInputs& inputs);
  void joinGroup();
  void sampleStep();
  double forwardBackward(bool polishing, double p);
  void addPlaneGradient();
  double reduceOverRanks(double loss);
  void optimizerStep(bool polishing);
  void report(bool polishing, double p);
  void writeCheckpointNow();
  // Adds the time since the last lap to one slot of the profile.
  void lap(double TrainResult::Profile::*slot) {
    const auto now = Clock::now();
    result_.profile.*slot += std::chrono::duration<double>(now - phaseStart_).count();
    phaseStart_ = now;
  }

  double elapsedTotal() const { return priorSeconds_ + secondsSince(callStart_); }
  // The time budget covers the whole call: the set-up, the loop (over resumed runs too) and
  // the final exact evaluation, whose cost is estimated from the measured step rate (a
  // forward pass over every group x image costs about a third of a training sample).
  double finalEvalSeconds() const {
    const double loopSeconds = secondsSince(loopStart_);
    if (!config_.finalEvaluation || step_ == firstStep_ || loopSeconds < 0.5) return 0.0;
    const double evalSamples = static_cast<double>(set_.groups()) * set_.images();
    return evalSamples / (3 * samplesPerSecond(loopSeconds));
  }
  double samplesPerSecond(double seconds) const {
    return (step_ - firstStep_) * static_cast<double>(geometry_.batch) / seconds;
  }
  double progressOf(std::int64_t s, double elapsed) const {
    double p = 0;
    if (geometry_.totalSteps > 0) p = static_cast<double>(s) / geometry_.totalSteps;
    if (config_.timeBudgetSeconds > 0) p = std::max(p, (elapsed + finalEvalSeconds()) / config_.timeBudgetSeconds);
    return std::min(1.0, p);
  }
  bool worker() const { return group_ && group_->rank() != 0; }
  // The per-texel latents' texture and their blur at training progress p (no texture and no
  // blur for clustered latents; the blur's clock is the polish phase).
  LatentImage latentImageAt(double p) const {
    LatentImage image;
    if (!set_.perTexel() || !(config_.latentBlurSigma > 0)) return image;
    image.width = latentWidth_, image.height = latentHeight_;
    const double q = config_.polishFraction > 0 ? (p - (1 - config_.polishFraction)) / config_.polishFraction : 1;
    image.sigma = detail::latentBlurSigma(config_.latentBlurSigma, config_.latentBlurHalfLife, q);
    return image;
  }
  int stepTiles() const { return tileShare_.second - tileShare_.first; }

  const TrainConfig& config_;
  const Clock::time_point callStart_;
  TrainingSet set_;
  const MatrixXfCol& x_;
  const EncoderInputSource inputSource_;

  // ---- The model
  Encoder encoder_;
  Decoder decoder_;
  bool stock_ = false;  // the torch backend: stock modules and autograd
  torch::Device device_ = torch::kCPU;
  std::vector<torch::Tensor> params_;
  std::unique_ptr<torch::optim::Optimizer> optimizer_;
  double planeRateFactor_ = 1;
  std::unique_ptr<DecoderBackprop> backprop_;
  int planeInputs_ = 0;
  int clusterInputs_ = 0, trailingInputs_ = 0;
  torch::Tensor clusterPlanes_;  // [groups, 3 R^2 G] per-cluster direction planes (undefined without)
  std::vector<float> stockInputGradient_;
  DirectionPlanes stepPlanes_;  // the planes as this step samples them
  double flopsPerSample_ = 0;
  PolishLatents polish_;
  int latentWidth_ = 0, latentHeight_ = 0;  // the texture of per-texel latents

  // ---- The plan, and this rank's share of every step's tiles (all of them in one process)
  TrainPlan geometry_;
  std::unique_ptr<detail::DistributedGroup> group_;
  std::pair<int, int> tileShare_;

  // ---- Where the run stands
  CheckpointMeta meta_;
  std::int64_t step_ = 0, firstStep_ = 0;
  double priorSeconds_ = 0, emaLoss_ = -1;
  double elapsedAtCheck_ = 0;  // the clock as wantsStep() read it, for this step's schedule
  TrainResult result_;

  // ---- Per-step buffers and the loop's bookkeeping
  StepPlan plan_;
  int outputs_ = 0, dirWidth_ = 0;
  double lossToTexelMse_ = 1, withinTrain_ = 0;
  torch::Tensor dirs_, targets_, dz_, tileSlot_, tileGroup_;
  torch::Tensor stepDirs_, stepTargets_, stepTileSlot_, stepTileGroup_;
  std::unique_ptr<Progress> bar_;
  bool barInSeconds_ = false;
  std::int64_t totalEpochs_ = 0;
  std::size_t shown_ = 0;
  Clock::time_point loopStart_, lastCheckpoint_, lastStatus_, phaseStart_;
};

// Model and optimizer, initialized from the seed.
// The blur is over per-texel latents that the polish phase moves: anything else has no
// texture to blur or nothing the blur could shape.
void TrainingRun::checkLatentBlur(const TrainInputs& inputs) {
  if (!set_.perTexel())
    throw Error("training.latent_blur_sigma blurs per-texel latents over the texture: it needs the per-texel "
                "model (--clusters 0), this run has " + std::to_string(set_.groups()) + " clusters");
  if (!(config_.latentLearningRate > 0) || !(config_.polishFraction > 0))
    throw Error("training.latent_blur_sigma blurs the free per-texel latents of the polish phase: it needs "
                "optimizer.latent_learning_rate > 0 and training.polish_fraction > 0");
  latentWidth_ = inputs.stack->width(), latentHeight_ = inputs.stack->height();
}

void TrainingRun::buildModel() {
  torch::manual_seed(config_.seed);
  encoder_ = Encoder(set_.images(), config_.model);
  decoder_ = Decoder(config_.model);
  stock_ = config_.backend == "torch";
  device_ = trainingDevice(config_);
  if (!device_.is_cpu()) encoder_->to(device_), decoder_->to(device_);
  params_ = encoder_->parameters();
  for (auto& p : decoder_->parameters()) params_.push_back(p);
  // Cluster planes: a parameter of the decoder module, so that checkpoints keep them.
  clusterInputs_ = set_.clusterPlaneInputs();
  if (clusterInputs_ > 0 && !device_.is_cpu())
    throw Error("cluster_planes: training with cluster planes runs on the CPU only (training.device \"cpu\")");
  if (clusterInputs_ > 0) {
    clusterPlanes_ = decoder_->register_parameter(
        "cluster_planes", torch::empty({set_.groups(), static_cast<std::int64_t>(set_.clusterPlaneValues())})
                              .uniform_(-detail::kPlaneInitScale, detail::kPlaneInitScale));
    params_.push_back(clusterPlanes_);
  }
  optimizer_ = makeOptimizer(config_, params_, decoder_->planes, clusterPlanes_);  // its rates are set before every step
  planeRateFactor_ = config_.planeLearningRate > 0 ? config_.planeLearningRate / config_.learningRate : 1;
  backprop_ = std::make_unique<DecoderBackprop>(decoder_, config_.model.latentDim);
  // Learned direction planes: their features are the last direction inputs, sampled anew
  // after every step that moved them; their gradient comes from the decoder's input gradient.
  planeInputs_ = set_.planeInputs();
  trailingInputs_ = planeInputs_ + clusterInputs_;
  backprop_->setTrailingInputGradient(trailingInputs_);
  backprop_->setBf16Products(resolvedProducts(config_) == "bf16");
  flopsPerSample_ = decoderShape(config_.model).flopsPerSample();
}

// Data-parallel: the rendezvous, and this rank's share of every step's tiles.
void TrainingRun::joinGroup() {
  const int tiles = geometry_.tiles;
  if (config_.timeBudgetSeconds > 0)
    throw Error("--time-budget cannot be used with --world-size > 1 (ranks must run the same steps); use --epochs");
  if (config_.resume) throw Error("--resume cannot be used with --world-size > 1");
  if (tiles < config_.distributed.worldSize)
    throw Error("--world-size " + std::to_string(config_.distributed.worldSize) + " exceeds the " +
                std::to_string(tiles) + " encoder inputs of a step: every rank needs at least one");
  tileShare(tiles, config_.distributed.rank, config_.distributed.worldSize, tileShare_.first, tileShare_.second);
  // The training set follows from the settings the pipeline listed, but it is what the
  // collectives' buffer sizes come from: checked too, so no rank reaches Gloo with others.
  DistributedConfig dist = config_.distributed;
  std::string holdout;
  for (int i : set_.holdoutImages()) holdout += (holdout.empty() ? "" : ",") + std::to_string(i);
  dist.mustAgree.push_back({"training set: encoder inputs", std::to_string(set_.groups())});
  dist.mustAgree.push_back({"training set: images", std::to_string(set_.images())});
  dist.mustAgree.push_back({"training set: texels", std::to_string(set_.texels())});
  dist.mustAgree.push_back({"training set: held-out images", holdout.empty() ? "none" : holdout});
  dist.mustAgree.push_back({"training set: per-texel modulation (checksum)", std::to_string(set_.texelCoefficientHash())});
  group_ = std::make_unique<detail::DistributedGroup>(dist);
}

void TrainingRun::resume() {
  meta_.fingerprint = checkpointFingerprint(config_, set_);
  meta_.totalSteps = geometry_.totalSteps;
  if (config_.warmStart && !checkpointExists(config_.checkpointPath))
    throw Error("training: a warm start needs the previous stage's checkpoint, \"" + config_.checkpointPath +
                "\" does not exist");
  if (!(config_.resume || config_.warmStart) || !checkpointExists(config_.checkpointPath)) return;
  CheckpointMeta saved = loadCheckpoint(config_.checkpointPath, meta_.fingerprint, *encoder_, *decoder_, *optimizer_,
                                        polish_, config_.latentLearningRate, !config_.warmStart);
  if (config_.resume && !config_.warmStart && saved.totalSteps != geometry_.totalSteps) {
    auto plan = [](std::int64_t steps) {
      return steps > 0 ? std::to_string(steps) + " steps" : std::string("a time budget only");
    };
    throw fileError(config_.checkpointPath,
                    "checkpoint of a run planned for " + plan(saved.totalSteps) + ", this run plans " +
                        plan(geometry_.totalSteps) + " (--epochs or the config's step bounds changed); the "
                        "learning-rate schedule spans the whole run, so resume with the options of the interrupted "
                        "run, or start over without --resume");
  }
  step_ = saved.step;
  priorSeconds_ = saved.elapsedSeconds;
  emaLoss_ = saved.emaLoss;
  result_.resumedFromStep = step_;
}

void TrainingRun::startLoop() {
  if (3 * config_.model.outputTerms != set_.outputs())
    throw Error("training: the decoder gives " + std::to_string(3 * config_.model.outputTerms) + " outputs but the " +
                "targets have " + std::to_string(set_.outputs()) + " (model.outputTerms must equal the modulation terms)");
  outputs_ = set_.outputs();
  // The loss is a mean over the decoder's outputs; per texel and channel it counts terms times.
  lossToTexelMse_ = outputs_ / 3.0;
  dirWidth_ = set_.directionWidth();
  const std::int64_t batch = geometry_.batch;
  dirs_ = torch::empty({batch, dirWidth_});
  targets_ = torch::empty({batch, outputs_});
  tileSlot_ = torch::empty({geometry_.tiles}, torch::kLong);
  tileGroup_ = torch::empty({geometry_.tiles}, torch::kLong);
  const int trainImages = static_cast<int>(set_.trainImages().size());
  for (int i : set_.trainImages()) withinTrain_ += set_.withinSse(i);
  withinTrain_ /= static_cast<double>(set_.texels()) * trainImages * 3;

  // The bar counts optimizer steps, or whole seconds of the budget when only a budget bounds
  // the run: units a user can compare with the summary.
  const std::int64_t totalSteps = geometry_.totalSteps;
  barInSeconds_ = totalSteps == 0;
  totalEpochs_ = totalSteps > 0 ? (totalSteps + geometry_.stepsPerEpoch - 1) / geometry_.stepsPerEpoch : 0;
  bar_ = std::make_unique<Progress>(
      barInSeconds_ ? "train (s)" : "train (steps)",
      static_cast<std::size_t>(barInSeconds_ ? std::ceil(config_.timeBudgetSeconds) : totalSteps), config_.progress);
  shown_ = barInSeconds_ ? static_cast<std::size_t>(priorSeconds_) : static_cast<std::size_t>(step_);
  bar_->advance(shown_);
  loopStart_ = Clock::now();
  lastCheckpoint_ = lastStatus_ = loopStart_;
  firstStep_ = step_;
  encoder_->train();
}

bool TrainingRun::wantsStep() {
  elapsedAtCheck_ = elapsedTotal();
  if (geometry_.totalSteps > 0 && step_ >= geometry_.totalSteps) return false;
  if (config_.timeBudgetSeconds > 0 && elapsedAtCheck_ + finalEvalSeconds() >= config_.timeBudgetSeconds) return false;
  if ((config_.stopFlag && config_.stopFlag->load()) || (config_.stopAtStep > 0 && step_ >= config_.stopAtStep) ||
      (config_.stopAtSeconds > 0 && elapsedAtCheck_ >= config_.stopAtSeconds)) {
    result_.interrupted = true;
    writeCheckpointNow();
    return false;
  }
  return true;
}

void TrainingRun::step() {
  const double p = progressOf(step_, elapsedAtCheck_);
  const bool polishing = config_.polishFraction > 0 && p >= 1 - config_.polishFraction;
  setLearningRate(*optimizer_, config_.learningRate * geometry_.learningRateScale * scheduleFactor(config_, p),
                  planeRateFactor_);
  phaseStart_ = Clock::now();
  sampleStep();
  double loss = forwardBackward(polishing, p);
  if (trailingInputs_ > 0) addPlaneGradient();
  if (group_) loss = reduceOverRanks(loss);
  if (!std::isfinite(loss))
    throw Error("training diverged at step " + std::to_string(step_) +
                " (loss is not finite); lower optimizer.learning_rate");
  optimizerStep(polishing);
  ++step_;
  emaLoss_ = emaLoss_ < 0 ? loss : 0.98 * emaLoss_ + 0.02 * loss;
  report(polishing, p);
}

// Which groups and images, then this rank's share of their directions and targets. The
// encoder still runs on every distinct input of the step, so its BatchNorm sees the same
// batch on every rank as in one process; only the decoder's rows (the cost) are split.
void TrainingRun::sampleStep() {
  const int perTile = geometry_.perTile, begin = tileShare_.first, tiles = stepTiles();
  planStep(set_, config_.seed, step_, geometry_.tiles, perTile, plan_);
  if (planeInputs_ > 0) {
    stepPlanes_ = exportPlanes(decoder_);
    set_.setPlaneFeatures(stepPlanes_);
  }
  float* d = dirs_.data_ptr<float>();
  float* y = targets_.data_ptr<float>();
  const std::vector<float>& allDirs = set_.directions();
  at::parallel_for(0, tiles, 1, [&](std::int64_t first, std::int64_t last) {
    for (std::int64_t t = first; t < last; ++t) {
      const int* img = &plan_.images[(begin + t) * perTile];
      set_.targets(plan_.tileGroup[begin + t], img, perTile, y + t * perTile * outputs_);
      for (int s = 0; s < perTile; ++s) {
        if (s + kPrefetchRows < perTile) {  // random images: request their rows early
          const float* ahead = &allDirs[static_cast<std::size_t>(img[s + kPrefetchRows]) * dirWidth_];
          __builtin_prefetch(ahead);
          __builtin_prefetch(ahead + dirWidth_ - 1);
        }
        std::memcpy(d + (t * perTile + s) * dirWidth_, &allDirs[static_cast<std::size_t>(img[s]) * dirWidth_],
                    dirWidth_ * sizeof(float));
      }
      if (clusterInputs_ > 0)
        set_.writeClusterPlaneFeatures(
            clusterPlanes_.data_ptr<float>() + plan_.tileGroup[begin + t] * set_.clusterPlaneValues(), img, perTile,
            d + t * perTile * dirWidth_);
    }
  });
  for (int t = 0; t < tiles; ++t) {
    tileSlot_.data_ptr<std::int64_t>()[t] = plan_.tileSlot[begin + t];
    tileGroup_.data_ptr<std::int64_t>()[t] = plan_.tileGroup[begin + t];
  }
  // Views of the step's rows (all of them unless this rank trains a share).
  const std::int64_t rows = static_cast<std::int64_t>(tiles) * perTile;
  stepDirs_ = dirs_.narrow(0, 0, rows);
  stepTargets_ = targets_.narrow(0, 0, rows);
  stepTileSlot_ = tileSlot_.narrow(0, 0, tiles);
  stepTileGroup_ = tileGroup_.narrow(0, 0, tiles);
  lap(&TrainResult::Profile::sampling);
}

// The loss of the step, with every gradient in place: through the encoder, or, while
// polishing, through the frozen (or free) latents.
double TrainingRun::forwardBackward(bool polishing, double p) {
  const int perTile = geometry_.perTile;
  double loss;
  if (!polishing) {
    torch::Tensor in =
        inputSource_.rows(plan_.distinctGroups.data(), static_cast<std::int64_t>(plan_.distinctGroups.size()));
    if (stock_) {
      // Autograd through encoder and decoder; the whole step is timed as the decoder's.
      torch::Tensor z = encoder_->forwardStock(in.to(device_)).index_select(0, stepTileSlot_.to(device_));
      loss = stockTrainStep(decoder_, params_, z, stepDirs_, stepTargets_, perTile, device_, trailingInputs_,
                            stockInputGradient_);
      lap(&TrainResult::Profile::decoder);
    } else {
      for (auto& p : encoder_->parameters()) p.mutable_grad() = torch::Tensor();
      torch::Tensor z = encoder_->forward(in).index_select(0, stepTileSlot_);
      lap(&TrainResult::Profile::encoder);
      loss = backprop_->trainStep(z.detach(), stepDirs_, stepTargets_, perTile, dz_);
      lap(&TrainResult::Profile::decoder);
      z.backward(dz_);
      lap(&TrainResult::Profile::encoder);
    }
    return loss;
  }
  if (!polish_.values.defined()) {
    // Freeze the encoder: from here on the decoder fits the latents that will be stored
    // (and, when they are free, they fit the decoder).
    polish_.start(encodeAll(encoder_, x_, stock_, device_), config_.latentLearningRate);
    for (auto& p : encoder_->parameters()) p.mutable_grad() = torch::Tensor();
  }
  lap(&TrainResult::Profile::encoder);
  loss = polishStep(polish_, stepTileGroup_, [&](const torch::Tensor& z) {
    return stock_ ? stockTrainStep(decoder_, params_, z.to(device_), stepDirs_, stepTargets_, perTile, device_,
                                   trailingInputs_, stockInputGradient_)
                  : backprop_->trainStep(z, stepDirs_, stepTargets_, perTile, dz_);
  }, stock_, dz_, latentImageAt(p));
  if (polish_.free())
    setLearningRate(*polish_.optimizer, config_.latentLearningRate * polishScheduleFactor(config_, p));
  lap(&TrainResult::Profile::decoder);
  return loss;
}

void TrainingRun::addPlaneGradient() {
  const int perTile = geometry_.perTile;
  const float* rowGradients = stock_ ? stockInputGradient_.data() : backprop_->inputGradient().data();
  const int* images = &plan_.images[static_cast<std::size_t>(tileShare_.first) * perTile];
  if (planeInputs_ > 0) {
    torch::Tensor gradient = torch::zeros_like(decoder_->planes);
    set_.addPlaneGradient(images, rowGradients, static_cast<std::int64_t>(stepTiles()) * perTile,
                          gradient.data_ptr<float>(), trailingInputs_);
    decoder_->planes.mutable_grad() = gradient;
  }
  if (clusterInputs_ > 0) {
    torch::Tensor gradient = torch::zeros_like(clusterPlanes_);
    float* g = gradient.data_ptr<float>();
    for (int t = 0; t < stepTiles(); ++t)
      set_.addClusterPlaneGradient(images + t * perTile, perTile,
                                   rowGradients + static_cast<std::size_t>(t) * perTile * trailingInputs_ + planeInputs_,
                                   trailingInputs_,
                                   g + plan_.tileGroup[tileShare_.first + t] * set_.clusterPlaneValues());
    clusterPlanes_.mutable_grad() = gradient;
  }
  lap(&TrainResult::Profile::decoder);
}

// The whole step's gradient and loss: each rank's (a mean over its rows) weighted by its
// share of the rows, summed over the ranks. Every rank then takes the same step.
double TrainingRun::reduceOverRanks(double loss) {
  const double weight = static_cast<double>(stepTiles()) / geometry_.tiles;
  std::vector<torch::Tensor> reduced = params_;
  if (polish_.free()) reduced.push_back(polish_.values);
  for (const torch::Tensor& p : reduced)
    if (p.grad().defined()) p.grad().mul_(weight);
  return group_->allReduceGradients(reduced, loss * weight);
}

void TrainingRun::optimizerStep(bool polishing) {
  if (stock_) {
    optimizer_->step();
  } else if (auto* adam = dynamic_cast<torch::optim::Adam*>(optimizer_.get())) {
    detail::fusedAdamStep(*adam);
  } else {
    optimizer_->step();
  }
  if (polishing && polish_.free()) detail::fusedAdamStep(*polish_.optimizer);
  lap(&TrainResult::Profile::optimizer);
}

// Progress, status line, monitor and periodic checkpoint.
void TrainingRun::report(bool polishing, double p) {
  const double now = elapsedTotal();
  const std::size_t done = barInSeconds_ ? static_cast<std::size_t>(now) : static_cast<std::size_t>(step_);
  if (done > shown_) bar_->advance(done - shown_), shown_ = done;
  const double sps = samplesPerSecond(std::max(1e-9, secondsSince(loopStart_)));
  const double rmseEstimate = std::sqrt(emaLoss_ * lossToTexelMse_ + withinTrain_);
  if (config_.monitor) {
    TrainStatus st;
    st.step = step_, st.totalSteps = geometry_.totalSteps, st.seconds = now, st.progress = progressOf(step_, now);
    st.loss = emaLoss_, st.rmseEstimate = rmseEstimate, st.samplesPerSecond = sps;
    st.learningRate = config_.learningRate * geometry_.learningRateScale * scheduleFactor(config_, p);
    st.polish = polishing;
    config_.monitor(st);
  }
  if (secondsSince(lastStatus_) > 0.5) {
    bar_->setStatus(formatStatus(emaLoss_, rmseEstimate, sps, sps * 3 * flopsPerSample_ / 1e9,
                                 step_ / geometry_.stepsPerEpoch + 1, totalEpochs_, polishing));
    lastStatus_ = Clock::now();
  }
  if (config_.checkpointSeconds > 0 && secondsSince(lastCheckpoint_) >= config_.checkpointSeconds) writeCheckpointNow();
}

void TrainingRun::writeCheckpointNow() {
  if (config_.checkpointPath.empty() || worker()) return;  // rank 0 checkpoints for all
  meta_.step = step_;
  meta_.elapsedSeconds = elapsedTotal();
  meta_.emaLoss = emaLoss_;
  saveCheckpoint(config_.checkpointPath, meta_, *encoder_, *decoder_, *optimizer_, polish_);
  lastCheckpoint_ = Clock::now();
}

TrainResult TrainingRun::finish() {
  TrainResult& result = result_;
  result.trainSeconds = secondsSince(loopStart_);
  bar_->finish();
  if (group_ && group_->calls() > 0) {
    result.allReduceBytesPerStep = group_->bytesReduced() / group_->calls();
    result.allReduceSecondsPerStep = group_->secondsInCollectives() / group_->calls();
  }
  result.steps = step_;
  result.epochsRun = static_cast<int>(step_ / geometry_.stepsPerEpoch);
  result.finalLoss = std::max(0.0, emaLoss_);
  result.encoderBlocks = encoder_->blocks;
  result.samplesPerSecond = result.trainSeconds > 0 ? samplesPerSecond(result.trainSeconds) : 0;
  result.products = resolvedProducts(config_);
  if (worker()) {
    // Rank 0 exports, evaluates and writes; this rank's part is done.
    result.worker = true;
    result.rmseTrain = result.rmseHoldout = -1;
    result.seconds = secondsSince(callStart_);
    return result;
  }

  // ---- Export: eval-mode latents, the decoder as an Mlp, the encoder's state.
  result.decoderGflops = result.samplesPerSecond * 3 * flopsPerSample_ / 1e9;
  result.holdoutImages = set_.holdoutImages();
  // The polish phase's latents are the ones the decoder was fitted to last (the encoder's
  // outputs, moved when free); without a polish phase, the encoder's.
  // A blur still on at the end is part of what the decoder saw: the file stores the latents
  // through it.
  torch::Tensor latents = polish_.values.defined() ? latentImageAt(1).view(polish_.values.detach())
                                                   : encodeAll(encoder_, x_, stock_, device_);
  if (!device_.is_cpu()) encoder_->to(torch::kCPU), decoder_->to(torch::kCPU);  // export and evaluate on the CPU
  result.latentRows = set_.groups();
  result.latents.assign(latents.data_ptr<float>(), latents.data_ptr<float>() + latents.numel());
  result.decoder = detail::exportDecoder(decoder_);
  result.planes = exportPlanes(decoder_);
  if (clusterInputs_ > 0) {
    RowPlanes& c = result.clusterPlanes;
    c.resolution = config_.model.clusterPlaneResolution, c.features = config_.model.clusterPlaneFeatures;
    c.rows = set_.groups();
    torch::Tensor v = clusterPlanes_.detach().to(torch::kCPU).contiguous();
    c.values.assign(v.data_ptr<float>(), v.data_ptr<float>() + v.numel());
  }
  set_.setPlaneFeatures(result.planes);  // the final planes, for the evaluation below
  result.encoderState = serializeModule(*encoder_);
  if (!config_.checkpointPath.empty() && !result.interrupted) writeCheckpointNow();

  // ---- Exact RMSE over texels x images x channels (eq. 10), from per-cluster sums.
  result.rmseTrain = result.rmseHoldout = -1;
  if (!result.interrupted) {
    if (config_.finalEvaluation) {
      detail::RmsError rmse = detail::evaluateRmse(set_, *backprop_, latents, config_.progress,
                                                   clusterInputs_ > 0 ? clusterPlanes_.data_ptr<float>() : nullptr);
      result.rmseTrain = rmse.train;
      result.rmseHoldout = rmse.holdout;
    }
    if (!set_.perTexel()) result.rmseFloor = std::sqrt(withinTrain_);
    if (!set_.plainWithinSse().empty()) {
      double sse = 0;
      for (int i : set_.trainImages()) sse += set_.plainWithinSse()[i];
      result.rmsePlainFloor = std::sqrt(sse / (static_cast<double>(set_.trainImages().size()) *
                                               static_cast<double>(set_.texels()) * 3.0));
    }
  }
  result.seconds = secondsSince(callStart_);
  return result;
}

}  // namespace

std::string resolvedProducts(const TrainConfig& config) {
  if (config.products != "auto") return config.products;
  return config.backend == "fused" && detail::bf16ProductsNative() ? "bf16" : "float";
}

TrainResult trainModel(const TrainInputs& inputs, const TrainConfig& config) {
  detail::quietTorchLogging();
  validateTrainConfig(config, "training config");
  // A step allocates and frees the same few-megabyte activation tensors every time: from the
  // heap their pages are reused, where fresh mmap blocks would fault in on every step.
  reuseFreedMemory();
  const auto callStart = Clock::now();
  torch::set_num_threads(config.threads > 0 ? config.threads : threadCount());
  TrainingRun run(inputs, config, callStart);
  run.resume();
  run.startLoop();
  while (run.wantsStep()) run.step();
  return run.finish();
}

}  // namespace nbtf
