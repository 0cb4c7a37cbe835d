#include "model/kernels/vector_kernels.h"

#include "util/simd.h"

namespace nbtf::detail {

NBTF_SIMD_CLONES float dot16(const float* __restrict a, const float* __restrict b, int n) {
  float acc[16] = {};
  int i = 0;
  for (; i + 16 <= n; i += 16)
    for (int k = 0; k < 16; ++k) acc[k] += a[i + k] * b[i + k];
  for (; i < n; ++i) acc[i % 16] += a[i] * b[i];
  float s = 0;
  for (float v : acc) s += v;
  return s;
}

NBTF_SIMD_CLONES void axpy(float a, const float* __restrict x, float* __restrict y, int n) {
  for (int i = 0; i < n; ++i) y[i] += a * x[i];
}

}  // namespace nbtf::detail
