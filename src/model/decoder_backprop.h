// Hand-written forward and backward pass of the decoder for one training step. PRIVATE to
// src/model/*.cpp (includes torch).
//
// Why not autograd: the decoder is where the flops are, and a step's batch has structure
// autograd cannot see. Rows come in tiles of S rows that share one latent, so the first
// layer splits into W_z z (once per tile) + W_d d (per row): no GEMM with K = 12 and no
// gradient for the direction inputs. All activations live in preallocated buffers, so a
// step allocates nothing large. Parameter gradients are written into the parameters' .grad
// tensors; the latent gradient is returned for the encoder's autograd backward.
#pragma once
#include <vector>

#include "model/torch_modules.h"

namespace nbtf::detail {

class DecoderBackprop {
 public:
  DecoderBackprop(Decoder decoder, int latentDim);

  // z: [tiles, latent], dirs: [tiles * rowsPerTile, 4]. Returns [tiles * rowsPerTile, 3]
  // (a view of an internal buffer, valid until the next call).
  torch::Tensor forward(const torch::Tensor& z, const torch::Tensor& dirs, int rowsPerTile);

  // Forward, mean squared error against targets [rows, 3], and backward. Sets the grad of
  // every decoder parameter (overwriting), stores dLoss/dz in dz [tiles, latent] and
  // returns the loss.
  double trainStep(const torch::Tensor& z, const torch::Tensor& dirs, const torch::Tensor& targets, int rowsPerTile,
                   torch::Tensor& dz);

 private:
  void ensureBuffers(std::int64_t rows);

  Decoder decoder_;
  int latentDim_;
  int layers_, width_;
  std::vector<torch::Tensor> hidden_;  // post-ReLU activations of layers 0 .. L-2, [rows, width]
  torch::Tensor out_, diff_;           // [rows, 3]
  torch::Tensor grad_[2];              // ping-pong [rows, width]
  std::vector<torch::Tensor> weightGrad_, biasGrad_;
};

}  // namespace nbtf::detail
