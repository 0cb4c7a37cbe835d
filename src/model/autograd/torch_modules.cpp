#include "model/autograd/torch_modules.h"

#include <cmath>
#include <cstring>

#include "model/autograd/batch_norm.h"
#include "model/autograd/conv_pool.h"
#include "model/autograd/small_linear.h"
#include "util/error.h"

namespace nbtf {

int encoderBlockCount(int imageCount, int configured) {
  int blocks = 0, length = imageCount;
  // MaxPool1d(k3, s3) maps L to floor(L / 3); keep at least 2 positions so BatchNorm has
  // more than one value per channel even when a step has a single encoder input.
  while (blocks < configured && length / 3 >= 2) length /= 3, ++blocks;
  return blocks;
}

std::vector<int> encoderWidths(int imageCount, const std::vector<int>& configured) {
  const int blocks = encoderBlockCount(imageCount, static_cast<int>(configured.size()));
  std::vector<int> widths(configured.begin(), configured.begin() + blocks);
  constexpr int kPaperImages = 6561, kPaperPooledLength = 243;
  if (imageCount <= kPaperImages || blocks < static_cast<int>(configured.size()) || widths.empty()) return widths;
  int length = imageCount;
  for (int b = 0; b < blocks; ++b) length /= 3;
  while (length / 3 >= kPaperPooledLength) {
    widths.push_back(2 * widths.back());
    length /= 3;
  }
  return widths;
}

Mlp decoderShape(const ModelConfig& model) {
  Mlp mlp;
  int in = model.latentDim + model.directionInputCount();
  for (int l = 0; l < model.decoderLayers; ++l) {
    bool last = l + 1 == model.decoderLayers;
    DenseLayer layer;
    layer.in = in;
    layer.out = last ? 3 * model.outputTerms : model.decoderWidth;
    layer.weight.assign(static_cast<std::size_t>(layer.in) * layer.out, 0.0f);
    layer.bias.assign(layer.out, 0.0f);
    layer.activation = last ? Activation::None : Activation::Relu;
    mlp.layers.push_back(std::move(layer));
    in = model.decoderWidth;
  }
  return mlp;
}

namespace detail {

EncoderImpl::EncoderImpl(int imageCount, const ModelConfig& model) {
  namespace nn = torch::nn;
  const std::vector<int> widths = encoderWidths(imageCount, model.encoderChannels);
  blocks = static_cast<int>(widths.size());
  int channels = 3, length = imageCount;
  for (int b = 0; b < blocks; ++b) {
    int out = widths[b];
    convs.push_back(register_module("conv" + std::to_string(b),
                                    nn::Conv1d(nn::Conv1dOptions(channels, out, 3).stride(1).padding(1))));
    norms.push_back(register_module("norm" + std::to_string(b), nn::BatchNorm1d(out)));
    channels = out;
    length /= 3;
  }
  toLatent = register_module("to_latent", nn::Linear(channels * length, model.latentDim));
}

torch::Tensor EncoderImpl::forward(const torch::Tensor& x) {
  torch::Tensor h = x;
  for (int b = 0; b < blocks; ++b) {
    h = convPool3(h, convs[b]->weight, convs[b]->bias);
    auto& norm = norms[b];
    h = is_training() ? batchNormTrain(h, norm->weight, norm->bias, norm->running_mean, norm->running_var,
                                       norm->num_batches_tracked, norm->options.momentum().value(), norm->options.eps())
                      : norm->forward(h);
  }
  return smallLinear(h.flatten(1), toLatent->weight, toLatent->bias);
}

torch::Tensor EncoderImpl::forwardStock(const torch::Tensor& x) {
  torch::Tensor h = x;
  for (int b = 0; b < blocks; ++b) h = norms[b]->forward(torch::max_pool1d(convs[b]->forward(h), 3, 3));
  return toLatent->forward(h.flatten(1));
}

DecoderImpl::DecoderImpl(const ModelConfig& model) {
  Mlp shape = decoderShape(model);
  for (std::size_t l = 0; l < shape.layers.size(); ++l)
    layers.push_back(register_module("linear" + std::to_string(l),
                                     torch::nn::Linear(shape.layers[l].in, shape.layers[l].out)));
  if (model.planeFeatures > 0) {
    planeResolution = model.planeResolution;
    planeFeatures = model.planeFeatures;
    DirectionPlanes shapeOnly;
    shapeOnly.resolution = planeResolution, shapeOnly.features = planeFeatures;
    // Small random values: features that differ from cell to cell from the start, so the
    // first layer's weights on them get gradients, but small beside the fixed inputs.
    planes = register_parameter("planes", torch::empty({static_cast<std::int64_t>(shapeOnly.valueCount())})
                                              .uniform_(-kPlaneInitScale, kPlaneInitScale));
  }
}

DirectionPlanes exportPlanes(const Decoder& decoder) {
  DirectionPlanes p;
  if (!decoder->planes.defined()) return p;
  p.resolution = decoder->planeResolution;
  p.features = decoder->planeFeatures;
  torch::Tensor v = decoder->planes.detach().to(torch::kCPU).contiguous();
  p.values.assign(v.data_ptr<float>(), v.data_ptr<float>() + v.numel());
  return p;
}

torch::Tensor DecoderImpl::forward(torch::Tensor x) {
  for (std::size_t l = 0; l < layers.size(); ++l) {
    x = layers[l]->forward(x);
    if (l + 1 < layers.size()) x = torch::relu(x);
  }
  return x;
}

Mlp exportDecoder(const Decoder& decoder) {
  Mlp mlp;
  for (std::size_t l = 0; l < decoder->layers.size(); ++l) {
    const auto& lin = decoder->layers[l];
    torch::Tensor w = lin->weight.detach().to(torch::kFloat).contiguous();
    torch::Tensor b = lin->bias.detach().to(torch::kFloat).contiguous();
    DenseLayer layer;
    layer.out = static_cast<int>(w.size(0));
    layer.in = static_cast<int>(w.size(1));
    layer.weight.assign(w.data_ptr<float>(), w.data_ptr<float>() + w.numel());
    layer.bias.assign(b.data_ptr<float>(), b.data_ptr<float>() + b.numel());
    layer.activation = l + 1 < decoder->layers.size() ? Activation::Relu : Activation::None;
    mlp.layers.push_back(std::move(layer));
  }
  return mlp;
}

void importDecoder(const Mlp& mlp, Decoder& decoder) {
  if (mlp.layers.size() != decoder->layers.size()) throw Error("importDecoder: layer count differs");
  torch::NoGradGuard noGrad;
  for (std::size_t l = 0; l < mlp.layers.size(); ++l) {
    const DenseLayer& layer = mlp.layers[l];
    auto& lin = decoder->layers[l];
    if (lin->weight.size(0) != layer.out || lin->weight.size(1) != layer.in)
      throw Error("importDecoder: layer " + std::to_string(l) + " shape differs");
    bool relu = l + 1 < mlp.layers.size();
    if (layer.activation != (relu ? Activation::Relu : Activation::None))
      throw Error("importDecoder: layer " + std::to_string(l) + " activation differs from the torch decoder");
    std::memcpy(lin->weight.data_ptr<float>(), layer.weight.data(), layer.weight.size() * sizeof(float));
    std::memcpy(lin->bias.data_ptr<float>(), layer.bias.data(), layer.bias.size() * sizeof(float));
  }
}

}  // namespace detail
}  // namespace nbtf
