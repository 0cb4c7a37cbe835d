// A linear layer for products too small for threaded BLAS, as one autograd operation.
// PRIVATE to src/model/ (includes torch).
//
// Why: the encoder's last layer maps 64 inputs x 3888 features to 8 latents each step. Through
// torch (OpenBLAS with OpenMP threads) that product ran slower on 2 threads than on one even on
// an idle machine, and many times slower when another process kept the cores busy: the threads
// wait for each other at every barrier. Here it is dot products and axpys
// over contiguous feature rows, each output row summed by one thread in a fixed order.
#pragma once
#include <torch/torch.h>

namespace nbtf::detail {

// x [batch, in], weight [out, in], bias [out] -> x weight^T + bias [batch, out], like
// torch::nn::functional::linear; gradients flow to x (when it requires grad), weight and bias.
torch::Tensor smallLinear(const torch::Tensor& x, const torch::Tensor& weight, const torch::Tensor& bias);

}  // namespace nbtf::detail
