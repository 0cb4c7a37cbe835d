#include "model/torch_modules.h"

#include <ATen/Parallel.h>

#include <cmath>
#include <cstring>

#include "util/error.h"

namespace nbtf {

int encoderBlockCount(int imageCount, int configured) {
  int blocks = 0, length = imageCount;
  // MaxPool1d(k3, s3) maps L to floor(L / 3); keep at least 2 positions so BatchNorm has
  // more than one value per channel even when a step has a single encoder input.
  while (blocks < configured && length / 3 >= 2) length /= 3, ++blocks;
  return blocks;
}

Mlp decoderShape(const ModelConfig& model) {
  Mlp mlp;
  int in = model.latentDim + 4;
  for (int l = 0; l < model.decoderLayers; ++l) {
    bool last = l + 1 == model.decoderLayers;
    DenseLayer layer;
    layer.in = in;
    layer.out = last ? 3 : model.decoderWidth;
    layer.weight.assign(static_cast<std::size_t>(layer.in) * layer.out, 0.0f);
    layer.bias.assign(layer.out, 0.0f);
    layer.activation = last ? Activation::None : Activation::Relu;
    mlp.layers.push_back(std::move(layer));
    in = model.decoderWidth;
  }
  return mlp;
}

namespace detail {
namespace {

// Autograd node of maxPool3: keeps the winning position (0..2) of every window.
struct MaxPool3Function : torch::autograd::Function<MaxPool3Function> {
  static torch::Tensor forward(torch::autograd::AutogradContext* ctx, const torch::Tensor& input) {
    torch::Tensor x = input.contiguous();
    TORCH_CHECK(x.dim() == 3 && x.scalar_type() == torch::kFloat, "maxPool3: expects float [batch, channels, length]");
    const std::int64_t rows = x.size(0) * x.size(1), length = x.size(2), pooled = length / 3;
    torch::Tensor out = torch::empty({x.size(0), x.size(1), pooled});
    torch::Tensor which = torch::empty({x.size(0), x.size(1), pooled}, torch::kByte);
    const float* src = x.data_ptr<float>();
    float* dst = out.data_ptr<float>();
    std::uint8_t* arg = which.data_ptr<std::uint8_t>();
    at::parallel_for(0, rows, 16, [&](std::int64_t begin, std::int64_t end) {
      for (std::int64_t r = begin; r < end; ++r) {
        const float* p = src + r * length;
        for (std::int64_t o = 0; o < pooled; ++o) {
          // Same rule as torch's kernel: a later value wins only if strictly greater (or NaN).
          float best = p[3 * o];
          std::uint8_t at = 0;
          for (std::uint8_t j = 1; j < 3; ++j) {
            float v = p[3 * o + j];
            if (v > best || std::isnan(v)) best = v, at = j;
          }
          dst[r * pooled + o] = best;
          arg[r * pooled + o] = at;
        }
      }
    });
    ctx->save_for_backward({which});
    ctx->saved_data["length"] = length;
    return out;
  }

  static torch::autograd::variable_list backward(torch::autograd::AutogradContext* ctx,
                                                 torch::autograd::variable_list grads) {
    torch::Tensor which = ctx->get_saved_variables()[0];
    const std::int64_t length = ctx->saved_data["length"].toInt();
    torch::Tensor g = grads[0].contiguous();
    const std::int64_t rows = which.size(0) * which.size(1), pooled = which.size(2);
    torch::Tensor gx = torch::empty({which.size(0), which.size(1), length});
    const float* src = g.data_ptr<float>();
    const std::uint8_t* arg = which.data_ptr<std::uint8_t>();
    float* dst = gx.data_ptr<float>();
    at::parallel_for(0, rows, 16, [&](std::int64_t begin, std::int64_t end) {
      for (std::int64_t r = begin; r < end; ++r) {
        float* q = dst + r * length;
        for (std::int64_t o = 0; o < pooled; ++o) {
          float v = src[r * pooled + o];
          std::uint8_t at = arg[r * pooled + o];
          q[3 * o] = at == 0 ? v : 0.0f;
          q[3 * o + 1] = at == 1 ? v : 0.0f;
          q[3 * o + 2] = at == 2 ? v : 0.0f;
        }
        for (std::int64_t i = 3 * pooled; i < length; ++i) q[i] = 0.0f;  // the dropped tail
      }
    });
    return {gx};
  }
};

}  // namespace

torch::Tensor maxPool3(const torch::Tensor& x) { return MaxPool3Function::apply(x); }

EncoderImpl::EncoderImpl(int imageCount, const ModelConfig& model) {
  namespace nn = torch::nn;
  blocks = encoderBlockCount(imageCount, static_cast<int>(model.encoderChannels.size()));
  features = nn::Sequential();
  int channels = 3, length = imageCount;
  for (int b = 0; b < blocks; ++b) {
    int out = model.encoderChannels[b];
    features->push_back(nn::Conv1d(nn::Conv1dOptions(channels, out, 3).stride(1).padding(1)));
    features->push_back(MaxPool3());
    features->push_back(nn::BatchNorm1d(out));
    channels = out;
    length /= 3;
  }
  register_module("features", features);
  toLatent = register_module("to_latent", nn::Linear(channels * length, model.latentDim));
}

torch::Tensor EncoderImpl::forward(const torch::Tensor& x) {
  torch::Tensor h = blocks > 0 ? features->forward(x) : x;
  return toLatent->forward(h.flatten(1));
}

DecoderImpl::DecoderImpl(const ModelConfig& model) {
  Mlp shape = decoderShape(model);
  for (std::size_t l = 0; l < shape.layers.size(); ++l)
    layers.push_back(register_module("linear" + std::to_string(l),
                                     torch::nn::Linear(shape.layers[l].in, shape.layers[l].out)));
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
