// Hand-written forward and backward pass of the decoder for one training step. PRIVATE to
// src/model/ (includes torch).
//
// Why not autograd: the decoder is where the flops are, and at width 106 the time goes to
// memory passes over [batch x 106] tensors as much as to the matrix products. Here the
// batch is cut into chunks of a few hundred rows; each thread runs a chunk through every
// layer and back while its activations are still in L2, with register-blocked products
// that apply the ReLU (or its mask) before storing (dense_kernels.h), and accumulates the
// weight gradients over its chunks. Activations carry a constant-1 column after the
// hidden units, so each layer's bias is one more row of its (transposed, padded) weight
// matrix and its gradient one more column of the weight gradient. Rows come in tiles that
// share one latent, so the first layer splits into W_z z (once per tile) + W_d d (per
// row): the latent part is one product per tile, not per row. Each chunk keeps
// its own gradient sums, added in chunk order afterwards, so results are bit-identical run
// to run whichever thread ran which chunk.
#pragma once
#include <vector>

#include "model/kernels/dense_kernels.h"
#include "model/autograd/torch_modules.h"

namespace nbtf::detail {

class DecoderBackprop {
 public:
  DecoderBackprop(Decoder decoder, int latentDim);

  // z: [tiles, latent], dirs: [tiles * rowsPerTile, direction inputs]. Returns [tiles * rowsPerTile, 3]
  // (a view of an internal buffer, valid until the next call).
  torch::Tensor forward(const torch::Tensor& z, const torch::Tensor& dirs, int rowsPerTile);

  // Forward, mean squared error against targets [rows, 3], and backward. Sets the grad of
  // every decoder parameter (overwriting), stores dLoss/dz in dz [tiles, latent] and
  // returns the loss.
  double trainStep(const torch::Tensor& z, const torch::Tensor& dirs, const torch::Tensor& targets, int rowsPerTile,
                   torch::Tensor& dz);

  // From now on trainStep also computes dLoss/d(input) for the last `count` direction inputs
  // of every row (the learned direction planes' features): inputGradient() [rows, count].
  void setTrailingInputGradient(int count) { trailingInputs_ = count; }
  const std::vector<float>& inputGradient() const { return inputGradient_; }

  // From now on trainStep's hidden-layer products (forward, weight gradient and the gradient
  // below, the bulk of its multiply-adds) take bfloat16 operands with float sums
  // (dense_kernels.h, `"training": {"products": "bf16"}`). forward() stays in float.
  void setBf16Products(bool on) { bf16_ = on; }

 private:
  // One thread's scratch: a chunk's activations and gradients (row stride stride_).
  struct Worker {
    AlignedFloats hidden;          // (layers - 1) x chunk x stride, post-ReLU, column width_ = 1
    AlignedFloats grad, grad2;     // chunk x stride
    std::vector<float> out;        // chunk x outputs
    AlignedFloats inputs;          // chunk x (direction inputs + 1): layer 0's left-hand side
    AlignedFloats layer0;          // (direction inputs + 1) x stride: layer0_ with the current tile's row
    AlignedFloats inputGrad;       // chunk x padded trailing inputs
    std::vector<Bf16> rows, gradPairs, hiddenPairs;  // bf16 operands (setBf16Products): chunk x stride
  };
  // One chunk's gradient sums. Threads take the next chunk as they free up (a thread slowed
  // by the host does not hold the other up), and the sums are added in chunk order.
  struct ChunkSums {
    AlignedFloats weightGrad;      // layers 1 .. layers - 1: [out x stride], bias in column width_
    AlignedFloats dirGrad;         // direction inputs x stride: dLoss/dW_d, transposed and padded
    std::vector<float> tileGrad;   // the chunk's tiles (from firstTile) x width: dLoss/d(W_z z + b)
    std::int64_t firstTile = 0;
    double loss = 0;
  };
  // Sets up the per-tile part of layer 0, the padded weights and the workers, then runs the
  // chunks on all threads.
  void run(const torch::Tensor& z, const torch::Tensor& dirs, const float* targets, int rowsPerTile, float* outRows);
  // Runs chunk c on worker k; targets == nullptr: forward only (outputs to outRows).
  void runChunk(Worker& k, std::int64_t c, std::int64_t rows, int rowsPerTile, const float* dirs, const float* targets,
                float* outRows);

  Decoder decoder_;
  int latentDim_, layers_, width_, outputs_;
  int dirWidth_;                         // direction inputs per row (4: the paper's stereographic pair)
  int stride_;                           // padded row length: width_ hidden units + the 1 column
  std::vector<std::size_t> gradOffset_;  // layer l >= 1 -> offset in Worker::weightGrad
  // Per call, for layers l >= 1: forward_[l] = [W^T; b^T] padded ([in + 1] x stride, the
  // product's right-hand side; hidden layers also map the 1 column to itself), backward_[l]
  // = W padded ([out x stride]). For the last layer both are [outputs x stride] (rowDots).
  std::vector<AlignedFloats> forward_, backward_;
  std::vector<Worker> workers_;
  std::vector<ChunkSums> chunkSums_;
  // (direction inputs + 1) x stride, refreshed every call: W_d transposed and padded, then the
  // row each chunk fills with its tile's W_z z + b (column width_ = 1: the next layer's 1 column).
  AlignedFloats layer0_;
  torch::Tensor perTile_;          // [tiles, width]: W_z z + b
  torch::Tensor out_;              // [rows, outputs]
  int trailingInputs_ = 0;
  bool bf16_ = false;
  // With bf16_, for hidden layers 1 .. L - 2: forward_ and backward_ as bfloat16 row pairs
  // (the sums' terms rounded up to an even count with a zero row).
  std::vector<std::vector<Bf16>> forwardBf16_, backwardBf16_;
  std::vector<float> inputGradient_;  // rows x trailingInputs_
  AlignedFloats trailingWeights_;  // W x padded trailingInputs_: the last columns of layer 0's weights
  std::vector<torch::Tensor> weightGrad_, biasGrad_;
};

}  // namespace nbtf::detail
