// Hand-written forward and backward pass of the decoder for one training step. PRIVATE to
// src/model/*.cpp (includes torch).
//
// Why not autograd: the decoder is where the flops are, and at width 106 the time goes to
// memory passes over [batch x 106] tensors as much as to the matrix products. Here the
// batch is cut into chunks of a few hundred rows; each thread runs a chunk through every
// layer and back while its activations are still in L2 (single-threaded BLAS products,
// bias/ReLU/masks in the same cache-resident pass), and accumulates the weight gradients
// over its chunks. Rows come in tiles that share one latent, so the first layer splits
// into W_z z (once per tile) + W_d d (per row): no product with K = 12 and no gradient for
// the direction inputs. A thread's share of the chunks is fixed by the thread count and the
// per-thread sums are added in thread order, so results are bit-identical run to run.
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
  // One thread's scratch (chunk activations) and gradient sums.
  struct Worker {
    std::vector<float> hidden;       // (layers - 1) x chunk x width, post-ReLU
    std::vector<float> grad, grad2;  // chunk x width
    std::vector<float> out;          // chunk x 3
    std::vector<float> weightGrad, biasGrad;  // all layers, concatenated
    std::vector<float> dirGrad;      // 4 x width: dLoss/dW_d, transposed
    std::vector<float> tileGrad;     // tiles x width: dLoss/d(W_z z + b)
    double loss = 0;
  };
  // Sets up the per-tile part of layer 0 and the workers, then runs them in parallel.
  void run(const torch::Tensor& z, const torch::Tensor& dirs, const float* targets, int rowsPerTile, float* outRows);
  // Runs the chunks of worker `w`; targets == nullptr: forward only (outputs to outRows).
  void runWorker(int w, int workers, std::int64_t rows, int rowsPerTile, const float* dirs, const float* targets,
                 float* outRows);

  Decoder decoder_;
  int latentDim_, layers_, width_;
  std::vector<std::int64_t> weightOffset_, biasOffset_;  // into Worker::weightGrad / biasGrad
  std::vector<Worker> workers_;
  std::vector<float> dirWeightT_;  // 4 x width: W_d transposed, refreshed every call
  torch::Tensor perTile_;          // [tiles, width]: W_z z + b
  torch::Tensor out_;              // [rows, 3]
  std::vector<torch::Tensor> weightGrad_, biasGrad_;
};

}  // namespace nbtf::detail
