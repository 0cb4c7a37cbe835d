#include "codec/mlp.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "util/error.h"

namespace nbtf {

std::size_t Mlp::parameterCount() const {
  std::size_t n = 0;
  for (const auto& l : layers) n += l.parameterCount();
  return n;
}

double Mlp::flopsPerSample() const {
  double f = 0;
  for (const auto& l : layers) f += 2.0 * l.in * l.out;
  return f;
}

void Mlp::validate() const {
  if (layers.empty()) throw Error("decoder has no layers");
  for (std::size_t i = 0; i < layers.size(); ++i) {
    const DenseLayer& l = layers[i];
    std::string name = "decoder layer " + std::to_string(i);
    if (l.in <= 0 || l.out <= 0)
      throw Error(name + ": bad shape " + std::to_string(l.out) + " x " + std::to_string(l.in));
    if (l.weight.size() != static_cast<std::size_t>(l.in) * l.out)
      throw Error(name + ": weight has " + std::to_string(l.weight.size()) + " values, expected " +
                  std::to_string(static_cast<std::size_t>(l.in) * l.out));
    if (l.bias.size() != static_cast<std::size_t>(l.out))
      throw Error(name + ": bias has " + std::to_string(l.bias.size()) + " values, expected " + std::to_string(l.out));
    if (i > 0 && l.in != layers[i - 1].out)
      throw Error(name + ": takes " + std::to_string(l.in) + " inputs but the previous layer gives " +
                  std::to_string(layers[i - 1].out));
    if (l.activation != Activation::None && l.activation != Activation::Relu && l.activation != Activation::Sigmoid)
      throw Error(name + ": unknown activation " + std::to_string(static_cast<int>(l.activation)));
    auto finite = [](float v) { return std::isfinite(v); };
    if (!std::all_of(l.weight.begin(), l.weight.end(), finite) || !std::all_of(l.bias.begin(), l.bias.end(), finite))
      throw Error(name + ": has a non-finite parameter");
  }
}

}  // namespace nbtf
