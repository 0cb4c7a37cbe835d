#include "support/torch_reference.h"

#include <algorithm>
#include <chrono>
#include <ctime>
#include <tuple>
#include <utility>

#include "model/autograd/batch_norm.h"
#include "model/autograd/conv_pool.h"
#include "model/autograd/decoder_backprop.h"
#include "model/autograd/fused_adam.h"
#include "model/autograd/small_linear.h"
#include "model/autograd/torch_modules.h"
#include "util/directions.h"
#include "util/random.h"

namespace nbtf {

ReferenceDecoder referenceDecoder(const ModelConfig& model, std::uint64_t seed, const RowMatrix& inputs) {
  torch::manual_seed(seed);
  detail::Decoder decoder(model);
  ReferenceDecoder r;
  r.exported = detail::exportDecoder(decoder);
  torch::NoGradGuard noGrad;
  torch::Tensor in = torch::from_blob(const_cast<float*>(inputs.data()), {inputs.rows(), inputs.cols()}).clone();
  torch::Tensor out = decoder->forward(in).contiguous();
  r.torchOutput.resize(out.size(0), out.size(1));
  std::copy(out.data_ptr<float>(), out.data_ptr<float>() + out.numel(), r.torchOutput.data());
  return r;
}

namespace {

// A seeded random decoder and training batch: tiles latents, tiles x rowsPerTile direction
// rows in [-1, 1) and targets in [0, 1).
struct DecoderBatch {
  detail::Decoder decoder;
  torch::Tensor z, dirs, targets;
};

DecoderBatch randomDecoderBatch(const ModelConfig& model, std::uint64_t seed, int tiles, int rowsPerTile) {
  torch::manual_seed(seed);
  detail::Decoder decoder(model);
  const int rows = tiles * rowsPerTile;
  torch::Tensor z = torch::randn({tiles, model.latentDim});
  torch::Tensor dirs = torch::rand({rows, static_cast<std::int64_t>(model.directionInputCount())}) * 2 - 1;
  torch::Tensor targets = torch::rand({rows, 3});
  return {decoder, z, dirs, targets};
}

}  // namespace

namespace {

// decoderBackpropError's and decoderInputGradientError's figures, from one batch.
std::pair<double, double> decoderBackpropErrors(const ModelConfig& model, std::uint64_t seed, int tiles,
                                                int rowsPerTile, int threads, bool bf16Products) {
  if (threads > 0) torch::set_num_threads(threads);
  auto [decoder, z, dirs, targets] = randomDecoderBatch(model, seed, tiles, rowsPerTile);

  // Autograd on the plain concatenated input.
  torch::Tensor zAuto = z.clone().requires_grad_(true), dirsAuto = dirs.clone().requires_grad_(true);
  torch::Tensor input = torch::cat({zAuto.repeat_interleave(rowsPerTile, 0), dirsAuto}, 1);
  torch::Tensor loss = torch::mse_loss(decoder->forward(input), targets);
  decoder->zero_grad();
  loss.backward();
  // The network's parameters (the direction planes, when the model has them, take no part:
  // the rows' direction inputs are given whole here).
  std::vector<torch::Tensor> expected;
  for (auto& p : decoder->parameters())
    if (p.grad().defined()) expected.push_back(p.grad().clone());
  expected.push_back(zAuto.grad().clone());
  // The gradient of the last few direction inputs (what the direction planes' features get).
  constexpr int kTrailing = 3;
  const torch::Tensor expectedInputs = dirsAuto.grad().narrow(1, dirs.size(1) - kTrailing, kTrailing).contiguous();

  // The hand-written pass.
  detail::DecoderBackprop backprop(decoder, model.latentDim);
  backprop.setBf16Products(bf16Products);
  backprop.setTrailingInputGradient(kTrailing);
  torch::Tensor dz;
  double manualLoss = backprop.trainStep(z, dirs, targets, rowsPerTile, dz);
  std::vector<torch::Tensor> got;
  for (auto& p : decoder->parameters())
    if (p.grad().defined()) got.push_back(p.grad().clone());
  got.push_back(dz);
  const torch::Tensor gotInputs =
      torch::from_blob(const_cast<float*>(backprop.inputGradient().data()), expectedInputs.sizes(), torch::kFloat);

  double scale = 0, err = std::abs(manualLoss - loss.item<double>()) / std::max(1e-30, loss.item<double>());
  for (auto& e : expected) scale = std::max(scale, e.abs().max().item<double>());
  for (std::size_t i = 0; i < got.size(); ++i)
    err = std::max(err, (got[i] - expected[i]).abs().max().item<double>() / scale);
  const double inputScale = std::max(1e-30, expectedInputs.abs().max().item<double>());
  return {err, (gotInputs - expectedInputs).abs().max().item<double>() / inputScale};
}

}  // namespace

double decoderBackpropError(const ModelConfig& model, std::uint64_t seed, int tiles, int rowsPerTile, int threads,
                            bool bf16Products) {
  return decoderBackpropErrors(model, seed, tiles, rowsPerTile, threads, bf16Products).first;
}

double decoderInputGradientError(const ModelConfig& model, std::uint64_t seed, int tiles, int rowsPerTile, int threads,
                                 bool bf16Products) {
  return decoderBackpropErrors(model, seed, tiles, rowsPerTile, threads, bf16Products).second;
}

std::vector<float> decoderTrainStepResult(const ModelConfig& model, std::uint64_t seed, int tiles, int rowsPerTile,
                                          int threads, bool bf16Products) {
  torch::set_num_threads(threads);
  auto [decoder, z, dirs, targets] = randomDecoderBatch(model, seed, tiles, rowsPerTile);
  detail::DecoderBackprop backprop(decoder, model.latentDim);
  backprop.setBf16Products(bf16Products);
  torch::Tensor dz;
  std::vector<float> result{static_cast<float>(backprop.trainStep(z, dirs, targets, rowsPerTile, dz))};
  std::vector<torch::Tensor> parts;
  for (auto& p : decoder->parameters())
    if (p.grad().defined()) parts.push_back(p.grad());
  parts.push_back(dz);
  for (auto& t : parts) {
    torch::Tensor c = t.contiguous();
    result.insert(result.end(), c.data_ptr<float>(), c.data_ptr<float>() + c.numel());
  }
  return result;
}

double convPoolReferenceError(std::uint64_t seed, int batch, int inChannels, int outChannels, int length) {
  torch::manual_seed(seed);
  namespace nn = torch::nn;
  nn::Conv1d conv(nn::Conv1dOptions(inChannels, outChannels, 3).stride(1).padding(1));
  {
    torch::NoGradGuard noGrad;
    conv->weight.copy_(torch::randint(-2, 3, conv->weight.sizes()));
    conv->bias.copy_(torch::randint(-2, 3, conv->bias.sizes()));
  }
  torch::Tensor x = torch::randint(-3, 4, {batch, inChannels, length}, torch::kFloat);
  torch::Tensor g = torch::randint(-3, 4, {batch, outChannels, length / 3}, torch::kFloat);
  torch::Tensor a = x.clone().requires_grad_(true), b = x.clone().requires_grad_(true);
  torch::Tensor ya = detail::convPool3(a, conv->weight, conv->bias);
  auto [gxa, gwa, gba] = [&] {
    auto grads = torch::autograd::grad({ya}, {a, conv->weight, conv->bias}, {g});
    return std::make_tuple(grads[0], grads[1], grads[2]);
  }();
  torch::Tensor yb = nn::MaxPool1d(nn::MaxPool1dOptions(3).stride(3))->forward(conv->forward(b));
  auto grads = torch::autograd::grad({yb}, {b, conv->weight, conv->bias}, {g});
  double err = (ya - yb).abs().max().item<double>();
  err = std::max(err, (gxa - grads[0]).abs().max().item<double>());
  err = std::max(err, (gwa - grads[1]).abs().max().item<double>());
  return std::max(err, (gba - grads[2]).abs().max().item<double>());
}

double smallLinearReferenceError(std::uint64_t seed, int batch, int in, int out) {
  torch::manual_seed(seed);
  torch::nn::Linear linear(in, out);
  {
    torch::NoGradGuard noGrad;
    linear->weight.copy_(torch::randint(-3, 4, linear->weight.sizes()));
    linear->bias.copy_(torch::randint(-3, 4, linear->bias.sizes()));
  }
  torch::Tensor x = torch::randint(-3, 4, {batch, in}, torch::kFloat);
  torch::Tensor g = torch::randint(-3, 4, {batch, out}, torch::kFloat);
  torch::Tensor a = x.clone().requires_grad_(true), b = x.clone().requires_grad_(true);
  torch::Tensor ya = detail::smallLinear(a, linear->weight, linear->bias);
  auto mine = torch::autograd::grad({ya}, {a, linear->weight, linear->bias}, {g});
  torch::Tensor yb = linear->forward(b);
  auto theirs = torch::autograd::grad({yb}, {b, linear->weight, linear->bias}, {g});
  double err = (ya - yb).abs().max().item<double>();
  for (int i = 0; i < 3; ++i) err = std::max(err, (mine[i] - theirs[i]).abs().max().item<double>());
  return err;
}

double fusedAdamReferenceError(std::uint64_t seed, const std::vector<std::int64_t>& sizes, int steps, double lr) {
  torch::manual_seed(seed);
  std::vector<torch::Tensor> mine, theirs;
  for (std::int64_t n : sizes) {
    torch::Tensor p = torch::randn({n});
    mine.push_back(p.clone().requires_grad_(true));
    theirs.push_back(p.clone().requires_grad_(true));
  }
  torch::optim::Adam a(mine, torch::optim::AdamOptions(lr)), b(theirs, torch::optim::AdamOptions(lr));
  for (int s = 0; s < steps; ++s) {
    for (std::size_t i = 0; i < sizes.size(); ++i) {
      torch::Tensor g = torch::randn({sizes[i]}) * (s % 3 + 1);
      mine[i].mutable_grad() = g.clone();
      theirs[i].mutable_grad() = g.clone();
    }
    detail::fusedAdamStep(a);
    b.step();
  }
  auto relative = [](const torch::Tensor& x, const torch::Tensor& y) {
    return (x - y).abs().max().item<double>() / std::max(1e-30, y.abs().max().item<double>());
  };
  double err = 0;
  for (std::size_t i = 0; i < sizes.size(); ++i) {
    err = std::max(err, relative(mine[i], theirs[i]));
    auto key = [](const torch::Tensor& p) { return c10::guts::to_string(p.unsafeGetTensorImpl()); };
    auto& sa = static_cast<torch::optim::AdamParamState&>(*a.state().at(key(mine[i])));
    auto& sb = static_cast<torch::optim::AdamParamState&>(*b.state().at(key(theirs[i])));
    if (sa.step() != sb.step()) return 1e30;
    err = std::max({err, relative(sa.exp_avg(), sb.exp_avg()), relative(sa.exp_avg_sq(), sb.exp_avg_sq())});
  }
  return err;
}

double batchNormReferenceError(std::uint64_t seed, int batch, int channels, int length, bool constantChannel,
                               int threads) {
  torch::set_num_threads(threads);
  torch::manual_seed(seed);
  namespace nn = torch::nn;
  nn::BatchNorm1d mine(channels), theirs(channels);
  {
    torch::NoGradGuard noGrad;
    torch::Tensor gamma = torch::rand({channels}) + 0.5, beta = torch::randn({channels});
    torch::Tensor runMean = torch::randn({channels}), runVar = torch::rand({channels}) + 0.5;
    for (nn::BatchNorm1d* m : {&mine, &theirs}) {
      (*m)->weight.copy_(gamma);
      (*m)->bias.copy_(beta);
      (*m)->running_mean.copy_(runMean);
      (*m)->running_var.copy_(runVar);
    }
  }
  torch::Tensor x = torch::randn({batch, channels, length}) * 3 + 1;
  if (constantChannel) x.select(1, 0).fill_(2.5);
  torch::Tensor g = torch::randn({batch, channels, length});
  torch::Tensor a = x.clone().requires_grad_(true), b = x.clone().requires_grad_(true);
  torch::Tensor ya = detail::batchNormTrain(a, mine->weight, mine->bias, mine->running_mean, mine->running_var,
                                            mine->num_batches_tracked, mine->options.momentum().value(),
                                            mine->options.eps());
  auto ga = torch::autograd::grad({ya}, {a, mine->weight, mine->bias}, {g});
  theirs->train();
  torch::Tensor yb = theirs->forward(b);
  auto gb = torch::autograd::grad({yb}, {b, theirs->weight, theirs->bias}, {g});
  // Each quantity's largest difference relative to its largest magnitude (at least 1): the
  // weight and bias gradients are sums over batch x length values.
  auto relative = [](const torch::Tensor& a, const torch::Tensor& b) {
    return (a - b).abs().max().item<double>() / std::max(1.0, b.abs().max().item<double>());
  };
  double err = relative(ya, yb);
  for (int i = 0; i < 3; ++i) err = std::max(err, relative(ga[i], gb[i]));
  err = std::max(err, relative(mine->running_mean, theirs->running_mean));
  err = std::max(err, relative(mine->running_var, theirs->running_var));
  if (mine->num_batches_tracked.item<std::int64_t>() != theirs->num_batches_tracked.item<std::int64_t>()) err = 1e30;
  return err;
}

DecoderStepRate decoderStepRate(const ModelConfig& model, int tiles, int rowsPerTile, int steps, int threads,
                                bool bf16Products) {
  torch::set_num_threads(threads);
  torch::manual_seed(0);
  detail::Decoder decoder(model);
  detail::DecoderBackprop backprop(decoder, model.latentDim);
  backprop.setBf16Products(bf16Products);
  const int rows = tiles * rowsPerTile;
  torch::Tensor z = torch::randn({tiles, model.latentDim}), y = torch::rand({rows, 3});
  // Direction inputs as training builds them (TrainingSet): the model's encoding of measured
  // (light, view) pairs, one pair per row; direction planes' features (if any) stay 0.
  const int width = model.directionInputCount();
  torch::Tensor dirs = torch::zeros({rows, width});
  const std::vector<Direction>& measured = hemisphere81();
  SplitMix64 pick(7);
  for (int r = 0; r < rows; ++r) {
    const Direction& light = measured[pick.next() % measured.size()];
    const Direction& view = measured[pick.next() % measured.size()];
    encodeDirections(model.directionInputs, light, view, dirs.data_ptr<float>() + static_cast<std::size_t>(r) * width);
  }
  torch::Tensor dz;
  backprop.trainStep(z, dirs, y, rowsPerTile, dz);  // warm-up
  auto cpu = [] {
    timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return t.tv_sec + t.tv_nsec * 1e-9;
  };
  double c0 = cpu();
  auto t0 = std::chrono::steady_clock::now();
  for (int s = 0; s < steps; ++s) backprop.trainStep(z, dirs, y, rowsPerTile, dz);
  DecoderStepRate r;
  r.wallSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.cpuSeconds = cpu() - c0;
  r.samplesPerSecond = static_cast<double>(rows) * steps / r.wallSeconds;
  return r;
}

double matmulGflops(int n, int threads, double minSeconds) {
  torch::set_num_threads(threads);
  torch::NoGradGuard noGrad;
  torch::manual_seed(0);
  torch::Tensor a = torch::randn({n, n}), b = torch::randn({n, n}), c = torch::empty({n, n});
  torch::mm_out(c, a, b);  // warm-up: thread pool, page faults
  double best = 0, total = 0;
  while (total < minSeconds) {
    auto t0 = std::chrono::steady_clock::now();
    torch::mm_out(c, a, b);
    double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    total += s;
    best = std::max(best, 2.0 * n * n * n / s / 1e9);
  }
  return best;
}

bool torchCudaAvailable() { return torch::cuda::is_available(); }

}  // namespace nbtf
