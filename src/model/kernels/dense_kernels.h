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
#include <cstdint>
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

// ---- Products of bfloat16 operands with float sums (`"training": {"products": "bf16"}`).
// The operands are rounded to bfloat16 (8 significant bits, float's exponent range) and
// every product is taken in pairs of consecutive terms of the sum, as the AVX-512 BF16
// instruction VDPBF16PS does: sum += a[2p + 1] b[2p + 1], then sum += a[2p] b[2p]. A product
// of two bfloat16 values is exact in float, so each step rounds once whether or not it is
// fused: the portable build gives the same bits as the instruction (except for a sum below
// 1.2e-38, which the instruction flushes to zero). Why: that instruction
// does twice the multiply-adds of a float FMA per cycle, and the decoder's training pass is
// its products. Sums still run in one fixed order, the same on every run.
using Bf16 = std::uint16_t;

// Round to nearest even; zero and subnormal inputs become (signed) zero, as VDPBF16PS reads them.
Bf16 toBf16(float value);
float fromBf16(Bf16 value);

// dst[r * ldd + j] = toBf16(src[r * lds + j]) for r < n, j < cols; dst's columns cols .. ldd are zeroed.
void toBf16Rows(int n, int cols, const float* src, int lds, Bf16* dst, int ldd);
// Row pairs interleaved: dst[((r / 2) * cols + j) * 2 + r % 2] = toBf16(src[r * lds + j]) for
// r < n, j < cols; an odd n gets a zero last row. The layout of a sum's pairs when the sum
// runs over rows (a right-hand matrix, or both sides of a weight gradient).
void toBf16RowPairs(int n, int cols, const float* src, int lds, Bf16* dst);

// y (+ epilogue) = x b as product/productRelu/productMasked above, with k even, x in
// bfloat16 rows (row stride ldx, even) and b in row pairs (toBf16RowPairs of k x cols);
// h: the ReLU outputs whose mask applies (productMasked), else nullptr.
enum class Bf16Epilogue { None, Relu, Mask };
void productBf16(Bf16Epilogue epilogue, int n, int k, const Bf16* x, int ldx, const Bf16* bPairs, int cols,
                 const float* h, float* y);
// w[i][j] += sum_{r<n} g[r][i] h[r][j] for i < m, j < cols, as accumulateOuter, with g and h
// in row pairs (toBf16RowPairs: g of n x ldg, h of n x cols).
void accumulateOuterBf16(int n, int m, const Bf16* gPairs, int ldg, const Bf16* hPairs, int cols, float* w);

// Whether this CPU has the instruction (AVX-512 BF16); without it the portable build runs,
// slower, with the same results. Tests only: force the portable build.
bool bf16ProductsNative();
void setBf16ProductsPortable(bool portable);

}  // namespace nbtf::detail
