// BatchNorm1d in training mode (batch statistics) as one autograd operation. PRIVATE to
// src/model/ (includes torch).
//
// Why: torch's CPU kernel for [batch, channels, length] with few channels (4, 8, 16 in the
// encoder) was a large part of the encoder's step. This one works a
// channel at a time over contiguous rows, threads over channels (so sums have a fixed order:
// deterministic for any thread count), and accumulates the statistics in double.
#pragma once
#include <torch/torch.h>

namespace nbtf::detail {

// y = (x - mean) / sqrt(var + eps) * gamma + beta with mean and (biased) var per channel over
// batch and length, as torch::nn::BatchNorm1d computes in train(). Updates the module's
// running statistics as torch does: running = (1 - momentum) running + momentum batch, the
// variance unbiased (n / (n - 1)), and counts the batch in numBatchesTracked. Gradients flow
// to x, gamma and beta.
torch::Tensor batchNormTrain(const torch::Tensor& x, const torch::Tensor& gamma, const torch::Tensor& beta,
                             torch::Tensor& runningMean, torch::Tensor& runningVar, torch::Tensor& numBatchesTracked,
                             double momentum, double eps);

}  // namespace nbtf::detail
