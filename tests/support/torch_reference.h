// libtorch-backed reference computations for tests and benchmarks. The header is
// torch-free; the work happens in torch_reference.cpp.
#pragma once
#include <cstdint>
#include <vector>

#include "support/mlp_reference.h"
#include "model/trainer.h"

namespace nbtf {

// A decoder initialized by torch from `seed`: its export as an Mlp, and torch's own forward
// pass (nn::Linear + ReLU) on `inputs`, to check that the export is exact.
struct ReferenceDecoder {
  Mlp exported;
  RowMatrix torchOutput;
};
ReferenceDecoder referenceDecoder(const ModelConfig& model, std::uint64_t seed, const RowMatrix& inputs);

// Runs the hand-written decoder backward pass that training uses and torch autograd on the
// same random batch (tiles x rowsPerTile rows); returns the largest difference over all
// parameter gradients and the latent gradient, relative to the largest gradient magnitude.
// threads > 0 sets torch's thread count first (the pass splits its rows among threads).
// bf16Products: the hand-written pass's products take bfloat16 operands (autograd stays float).
double decoderBackpropError(const ModelConfig& model, std::uint64_t seed, int tiles, int rowsPerTile,
                            int threads = 0, bool bf16Products = false);
// The same pass's gradient of the last 3 direction inputs of every row (what the direction
// planes' features get): the largest difference relative to its largest magnitude.
double decoderInputGradientError(const ModelConfig& model, std::uint64_t seed, int tiles, int rowsPerTile,
                                 int threads = 0, bool bf16Products = false);

// The hand-written decoder pass's loss, every parameter gradient and the latent gradient,
// concatenated, for a random batch like decoderBackpropError's, on `threads` threads.
std::vector<float> decoderTrainStepResult(const ModelConfig& model, std::uint64_t seed, int tiles, int rowsPerTile,
                                          int threads, bool bf16Products = false);

// The encoder's fused conv + pool (conv_pool.h) against torch::nn::Conv1d(k3, s1, p1) then
// MaxPool1d(3, stride 3), on small-integer inputs, weights and output gradients (so both
// compute exactly and ties are common): the largest difference of outputs and of the input,
// weight and bias gradients (0 when they agree exactly).
double convPoolReferenceError(std::uint64_t seed, int batch, int inChannels, int outChannels, int length);

// The encoder's last layer (smallLinear, small_linear.h) against torch::nn::Linear on
// small-integer inputs, weights and output gradients: the largest difference of outputs and
// of the input, weight and bias gradients (0 when they agree exactly).
double smallLinearReferenceError(std::uint64_t seed, int batch, int in, int out);

// The encoder's BatchNorm in training (batchNormTrain, batch_norm.h) against
// torch::nn::BatchNorm1d in train(), on random normal inputs and output gradients (one channel
// constant when constantChannel): the largest difference, relative to the largest magnitude
// (at least 1), of outputs, the input, weight and bias gradients, and the running mean and
// variance after the step, on `threads` threads. Float rounding differs (torch sums in float, in
// an order that depends on its thread count), so not 0.
double batchNormReferenceError(std::uint64_t seed, int batch, int channels, int length, bool constantChannel,
                               int threads);

// detail::fusedAdamStep against torch::optim::Adam::step: the same random parameters
// (tensors of the given sizes) and gradients for `steps` steps, lr and betas as given;
// returns the largest parameter difference relative to the largest parameter magnitude,
// after checking that both optimizers' states (step count, moments) agree likewise.
double fusedAdamReferenceError(std::uint64_t seed, const std::vector<std::int64_t>& sizes, int steps, double lr);

// The decoder's hand-written training pass alone (forward, loss, backward; no encoder, no
// optimizer) on random data: `steps` steps of tiles x rowsPerTile rows on `threads` threads,
// its hidden-layer products in float or with bfloat16 operands (`"training": {"products"}`).
struct DecoderStepRate {
  double samplesPerSecond = 0;  // wall clock
  double cpuSeconds = 0, wallSeconds = 0;
};
DecoderStepRate decoderStepRate(const ModelConfig& model, int tiles, int rowsPerTile, int steps, int threads,
                                bool bf16Products);

// libtorch's float32 matrix-multiply rate (n x n times n x n, `threads` threads), GFLOP/s,
// the best of repeated runs taking at least minSeconds in all.
double matmulGflops(int n, int threads, double minSeconds);

// Whether this libtorch can run on a CUDA device (Debian's cannot).
bool torchCudaAvailable();

}  // namespace nbtf
