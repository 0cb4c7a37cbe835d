#include "support/mlp_reference.h"

#include <algorithm>
#include <string>

#include "util/error.h"
#include "util/parallel.h"

namespace nbtf {

namespace {

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

RowMatrix mlpForward(const Mlp& mlp, const RowMatrix& inputs) {
  const auto& layers = mlp.layers;
  if (layers.empty()) throw Error("mlpForward: the network has no layers");
  if (inputs.cols() != mlp.inputSize())
    throw Error("mlpForward: inputs have " + std::to_string(inputs.cols()) + " columns, the network takes " +
                std::to_string(mlp.inputSize()));
  const Eigen::Index rows = inputs.rows();
  RowMatrix out(rows, mlp.outputSize());
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
