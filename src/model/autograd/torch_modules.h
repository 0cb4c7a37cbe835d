// The encoder and decoder as torch modules. PRIVATE to src/model/: it includes torch,
// which must stay out of every public header (20 s per translation unit).
#pragma once
#include <torch/torch.h>

#include "codec/mlp.h"
#include "model/trainer.h"

namespace nbtf::detail {

// N_blocks x [Conv1d(k3, s1, p1) -> MaxPool1d(k3, s3) -> BatchNorm1d], then a linear map
// of the flattened features to the latent. Input [batch, 3, N] (RGB channels x images).
// The Conv1d and Linear modules hold the parameters (torch's initialization); conv + pool
// run fused (conv_pool.h), BatchNorm in training as batchNormTrain (batch_norm.h), the
// linear map as smallLinear (small_linear.h).
struct EncoderImpl : torch::nn::Module {
  EncoderImpl(int imageCount, const ModelConfig& model);
  torch::Tensor forward(const torch::Tensor& x);
  // The same function through stock torch modules (Conv1d, max_pool1d, BatchNorm1d, Linear):
  // what the torch training backend differentiates by autograd, on any device.
  torch::Tensor forwardStock(const torch::Tensor& x);

  int blocks = 0;
  std::vector<torch::nn::Conv1d> convs;
  std::vector<torch::nn::BatchNorm1d> norms;
  torch::nn::Linear toLatent{nullptr};
};
TORCH_MODULE(Encoder);

// Linear layers, ReLU between, linear RGB output. Input [batch, latent + 4]:
// latent, stereographic light (x, y), stereographic view (x, y).
constexpr float kPlaneInitScale = 0.1f;  // direction planes start uniform in [-0.1, 0.1]

struct DecoderImpl : torch::nn::Module {
  explicit DecoderImpl(const ModelConfig& model);
  torch::Tensor forward(torch::Tensor x);

  std::vector<torch::nn::Linear> layers;
  // The learned direction planes, flat in DirectionPlanes::values' layout (undefined without).
  // Their features are inputs of layers[0]; the trainer samples them (TrainingSet).
  torch::Tensor planes;
  int planeResolution = 0, planeFeatures = 0;
};
TORCH_MODULE(Decoder);

// torch nn::Linear weights are out x in, row-major: the DenseLayer layout, copied as is.
Mlp exportDecoder(const Decoder& decoder);
// The planes as they are now (empty without planes).
DirectionPlanes exportPlanes(const Decoder& decoder);
void importDecoder(const Mlp& mlp, Decoder& decoder);

}  // namespace nbtf::detail
