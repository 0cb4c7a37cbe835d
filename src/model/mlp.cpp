#include "model/mlp.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "util/error.h"
#include "util/parallel.h"

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

namespace {

using RowMatrix = Mlp::RowMatrix;
using WeightMap = Eigen::Map<const RowMatrix>;
using BiasMap = Eigen::Map<const Eigen::RowVectorXf>;

// y = activation(x W^T + b) for one block of rows.
template <class In, class Out>
void denseLayer(const DenseLayer& l, const In& x, Out&& y) {
  WeightMap w(l.weight.data(), l.out, l.in);
  BiasMap bias(l.bias.data(), l.out);
  y.noalias() = x * w.transpose();
  y.rowwise() += bias;
  switch (l.activation) {
    case Activation::Relu: y = y.cwiseMax(0.0f); break;
    case Activation::Sigmoid: y = (1.0f + (-y.array()).exp()).inverse().matrix(); break;
    case Activation::None: break;
  }
}

// One block of rows through every layer. The block is small enough that its
// activations stay in cache between layers; each layer is one Eigen GEMM.
void forwardBlock(const std::vector<DenseLayer>& layers, const Eigen::Ref<const RowMatrix>& in,
                  Eigen::Ref<RowMatrix> out, RowMatrix& a, RowMatrix& b) {
  if (layers.size() == 1) {
    denseLayer(layers[0], in, out);
    return;
  }
  a.resize(in.rows(), layers[0].out);
  denseLayer(layers[0], in, a);
  RowMatrix *cur = &a, *next = &b;
  for (std::size_t i = 1; i + 1 < layers.size(); ++i) {
    next->resize(in.rows(), layers[i].out);
    denseLayer(layers[i], *cur, *next);
    std::swap(cur, next);
  }
  denseLayer(layers.back(), *cur, out);
}

}  // namespace

RowMatrix Mlp::forward(const RowMatrix& inputs) const {
  if (layers.empty()) throw Error("Mlp::forward: the network has no layers");
  if (inputs.cols() != inputSize())
    throw Error("Mlp::forward: inputs have " + std::to_string(inputs.cols()) + " columns, the network takes " +
                std::to_string(inputSize()));
  const Eigen::Index rows = inputs.rows();
  RowMatrix out(rows, outputSize());
  if (rows == 0) return out;
  // Blocks of rows: large enough for efficient GEMM panels, small enough that a block's
  // activations (rows x width floats) stay in L2 between layers.
  const Eigen::Index blockRows = 512;
  const std::size_t blocks = static_cast<std::size_t>((rows + blockRows - 1) / blockRows);
  parallelFor(blocks, [&](std::size_t begin, std::size_t end) {
    RowMatrix a, b;
    for (std::size_t blk = begin; blk < end; ++blk) {
      Eigen::Index r0 = static_cast<Eigen::Index>(blk) * blockRows, n = std::min(blockRows, rows - r0);
      forwardBlock(layers, inputs.middleRows(r0, n), out.middleRows(r0, n), a, b);
    }
  });
  return out;
}

}  // namespace nbtf
