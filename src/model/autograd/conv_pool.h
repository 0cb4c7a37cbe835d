// The encoder's block body, Conv1d(kernel 3, stride 1, padding 1) followed by
// MaxPool1d(kernel 3, stride 3), as one fused autograd operation. PRIVATE to src/model/
// (includes torch).
//
// Why: with 3 -> 4 channels over 6561 positions, torch's CPU convolution (im2col + a GEMM
// with an inner size of 9) ran at a few GFLOP/s and made the encoder cost more than the
// decoder it feeds. Here each batch item is split into phase rows (conv_pool_kernels.h): the
// convolution, its transpose and its weight gradient become register-blocked FMAs over whole
// vectors of pooling windows, and pooling and its gradient are lane-wise.
#pragma once
#include <torch/torch.h>

namespace nbtf::detail {

// x [batch, in, length], weight [out, in, 3], bias [out] -> [batch, out, length / 3]:
// max over each window of 3 of the zero-padded convolution (positions beyond 3 * (length / 3)
// are dropped, as MaxPool1d does). Ties: the first maximum wins, like torch's kernel.
// Gradients flow to x (when it requires grad), weight and bias; values and gradients match
// torch's Conv1d + MaxPool1d up to float rounding. Deterministic for any thread count.
torch::Tensor convPool3(const torch::Tensor& x, const torch::Tensor& weight, const torch::Tensor& bias);

}  // namespace nbtf::detail
