// A plain (torch-free) multilayer perceptron: the decoder as it is stored in a .nbtf file
// and evaluated at decode time (codec/decoder_kernels.h). Training (model/trainer.h) produces
// one; the codec stores it.
#pragma once
#include <cstdint>
#include <vector>

namespace nbtf {

enum class Activation : std::uint8_t { None = 0, Relu = 1, Sigmoid = 2 };

struct DenseLayer {
  int in = 0, out = 0;
  std::vector<float> weight;  // out x in, row-major (torch's nn::Linear layout)
  std::vector<float> bias;    // out
  Activation activation = Activation::None;
  std::size_t parameterCount() const { return weight.size() + bias.size(); }
};

struct Mlp {
  std::vector<DenseLayer> layers;

  int inputSize() const { return layers.empty() ? 0 : layers.front().in; }
  int outputSize() const { return layers.empty() ? 0 : layers.back().out; }
  std::size_t parameterCount() const;
  // Forward-pass FLOPs per sample (multiply-adds counted as 2).
  double flopsPerSample() const;

  // Checks every layer's shapes chain and all parameters are finite; throws nbtf::Error.
  void validate() const;
};

}  // namespace nbtf
