// Contiguous float vector kernels shared by the hand-written encoder layers (conv_pool.cpp,
// small_linear.cpp). Torch-free; each has per-instruction-set clones (util/simd.h).
#pragma once

namespace nbtf::detail {

// sum over i < n of a[i] * b[i], in 16 interleaved partial sums reduced in lane order
// (vectorizable without reassociating, so the result is the same on every run).
float dot16(const float* a, const float* b, int n);

// y[i] += a * x[i] for i < n.
void axpy(float a, const float* x, float* y, int n);

}  // namespace nbtf::detail
