// Register-blocked dense products for the decoder's training pass (decoder_backprop.cpp).
// Torch-free.
//
// Why not BLAS: the decoder's products are small (a few hundred rows x 106 x 106 per
// call), where OpenBLAS spends a good part of its time packing the operands and the
// element-wise passes around it (bias, ReLU, ReLU mask) stream the activations once more.
// These kernels keep a block of rows x up to 112 columns of the result in vector registers
// through the whole inner sum, read the right-hand matrix in its natural row-major layout
// (no packing), and apply the ReLU or its mask before storing.
//
// Layout: row-major; a matrix with `cols` columns has row stride `cols` unless a stride
// is given; `cols` is a multiple of kDenseLanes (pad with zero columns). Every sum runs in
// one fixed order (products and outer sums: index increasing), the same on every run.
#pragma once
#include <cstddef>
#include <vector>

#include "util/simd.h"

namespace nbtf::detail {

constexpr int kDenseLanes = 16;
inline int paddedWidth(int width) { return (width + kDenseLanes - 1) / kDenseLanes * kDenseLanes; }

// y[r][j] = max(0, sum_{q<k} x[r * ldx + q] b[q][j]) for r < n, j < cols.
void productRelu(int n, int k, const float* x, int ldx, const float* b, int cols, float* y);

// y[r][j] = sum_{q<k} x[r * ldx + q] b[q][j] for r < n, j < cols (no epilogue).
void product(int n, int k, const float* x, int ldx, const float* b, int cols, float* y);

// y[r][j] = h[r][j] > 0 ? sum_{q<k} x[r * ldx + q] b[q][j] : 0 (the ReLU's backward, h its output).
void productMasked(int n, int k, const float* x, int ldx, const float* b, int cols, const float* h, float* y);

// w[i][j] += sum_{r<n} g[r * ldg + i] h[r][j] for i < m, j < cols (a weight gradient).
void accumulateOuter(int n, int m, const float* g, int ldg, const float* h, int cols, float* w);

// The kernels come in three builds (dense_kernels.cpp): Wide (AVX-512), Mid (AVX2 + FMA) and
// Narrow (any CPU); Auto picks the widest the CPU runs. Tests only: force one, so that every
// build this CPU supports is tested here (setDenseKernelTier throws for one it cannot run).
enum class DenseKernelTier { Auto, Narrow, Mid, Wide };
bool denseKernelTierSupported(DenseKernelTier tier);
void setDenseKernelTier(DenseKernelTier tier);

// out[r * m + i] = sum_{j<cols} h[r][j] w[i][j] for r < n, i < m (a narrow output layer).
void rowDots(int n, int m, const float* h, int cols, const float* w, float* out);

}  // namespace nbtf::detail
