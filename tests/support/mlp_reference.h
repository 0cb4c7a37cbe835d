// The plain decoder's forward pass in Eigen, one GEMM per layer: the reference that the
// decoder's hand-written kernels (codec/decoder_kernels.h) and the exported training model
// are checked against in tests. Not part of any library a user links.
#pragma once
#include <Eigen/Core>

#include "codec/mlp.h"

namespace nbtf {

using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Batched forward pass: inputs is batch x inputSize (row-major), returns batch x outputSize.
RowMatrix mlpForward(const Mlp& mlp, const RowMatrix& inputs);

}  // namespace nbtf
