#include "model/kernels/conv_pool_kernels.h"

#include <algorithm>

#include "util/simd.h"

namespace nbtf::detail::phases {
namespace {

// One vector of kLanes windows (GCC vector extension: each clone lowers it to its own
// registers, 1 zmm, 2 ymm or 4 xmm).
typedef float Vec __attribute__((vector_size(kLanes * sizeof(float))));

// Unaligned vector access to float rows (may_alias: read and written as floats elsewhere).
typedef float UnalignedVec __attribute__((vector_size(kLanes * sizeof(float)), aligned(4), may_alias));
#define NBTF_LOAD(p) (*reinterpret_cast<const UnalignedVec*>(p))
#define NBTF_STORE(p, v) (*reinterpret_cast<UnalignedVec*>(p) = (v))
// x in every lane. (Not x - Vec{}: where a Vec spans several registers GCC lowers that lane
// by lane, with AVX2 20 times slower.)
static_assert(kLanes == 16, "NBTF_BROADCAST lists 16 lanes");
#define NBTF_BROADCAST(x) Vec{x, x, x, x, x, x, x, x, x, x, x, x, x, x, x, x}
#define NBTF_INLINE inline __attribute__((always_inline))

// B destination channels x 3 rows of accumulators stay in registers over all source
// channels: each source vector is loaded once and feeds 9 B FMAs.
template <int B>
NBTF_INLINE void convolveBlock(const float* src, int srcChannels, int stride, const float* coef, const float* bias,
                               int vectors, float* dst, int dstStride) {
  for (int v = 0; v < vectors; ++v) {
    Vec acc[B][3] = {};
#pragma GCC unroll 8
    for (int d = 0; d < B; ++d) {
      const float b = bias ? bias[d] : 0.0f;
      acc[d][0] = acc[d][1] = acc[d][2] = NBTF_BROADCAST(b);
    }
    for (int s = 0; s < srcChannels; ++s) {
      const float* row = src + static_cast<std::ptrdiff_t>(s) * 3 * stride + v * kLanes;
      const Vec in[5] = {NBTF_LOAD(row), NBTF_LOAD(row + stride), NBTF_LOAD(row + 2 * stride), NBTF_LOAD(row + 1),
                         NBTF_LOAD(row + stride + 1)};
#pragma GCC unroll 8
      for (int d = 0; d < B; ++d) {
        const float* w = coef + (static_cast<std::ptrdiff_t>(d) * srcChannels + s) * 3;
#pragma GCC unroll 3
        for (int t = 0; t < 3; ++t) {
          const float wt = w[t];
          const Vec weight = NBTF_BROADCAST(wt);
#pragma GCC unroll 3
          for (int j = 0; j < 3; ++j) acc[d][j] += weight * in[j + t];
        }
      }
    }
#pragma GCC unroll 8
    for (int d = 0; d < B; ++d)
      for (int j = 0; j < 3; ++j)
        NBTF_STORE(dst + static_cast<std::ptrdiff_t>(d * 3 + j) * dstStride + v * kLanes, acc[d][j]);
  }
}

// The lanes of *v added by halves (a fixed order): a few vector adds rather than 16
// dependent scalar ones, which cost as much as the FMAs when a row is a few vectors long.
NBTF_INLINE float laneSum(const Vec* v) {
  typedef float Half __attribute__((vector_size(kLanes / 2 * sizeof(float))));
  typedef float Quarter __attribute__((vector_size(kLanes / 4 * sizeof(float))));
  Half lo, hi;
  __builtin_memcpy(&lo, v, sizeof lo);
  __builtin_memcpy(&hi, reinterpret_cast<const char*>(v) + sizeof lo, sizeof hi);
  const Half half = lo + hi;
  Quarter a, b;
  __builtin_memcpy(&a, &half, sizeof a);
  __builtin_memcpy(&b, reinterpret_cast<const char*>(&half) + sizeof a, sizeof b);
  const Quarter q = a + b;
  return (q[0] + q[1]) + (q[2] + q[3]);
}

// B output channels x 3 taps of accumulators over all windows for one input channel.
template <int B>
NBTF_INLINE void weightGradientBlock(const float* g, const float* x, int stride, int vectors, float* sums) {
  Vec acc[B][3] = {};
  for (int v = 0; v < vectors; ++v) {
    const float* xr = x + v * kLanes;
    const Vec in[5] = {NBTF_LOAD(xr), NBTF_LOAD(xr + stride), NBTF_LOAD(xr + 2 * stride), NBTF_LOAD(xr + 1),
                       NBTF_LOAD(xr + stride + 1)};
#pragma GCC unroll 8
    for (int d = 0; d < B; ++d) {
      // The convolution's gradient at 3p + j: phase rows 1, 2 at p and row 0 at p + 1.
      const float* gr = g + static_cast<std::ptrdiff_t>(d) * 3 * stride + v * kLanes;
      const Vec gj[3] = {NBTF_LOAD(gr + stride), NBTF_LOAD(gr + 2 * stride), NBTF_LOAD(gr + 1)};
#pragma GCC unroll 3
      for (int j = 0; j < 3; ++j)
#pragma GCC unroll 3
        for (int t = 0; t < 3; ++t) acc[d][t] += gj[j] * in[j + t];
    }
  }
  for (int d = 0; d < B; ++d)
    for (int t = 0; t < 3; ++t) sums[d * 3 + t] = laneSum(&acc[d][t]);
}

}  // namespace

int rowStride(int length) { return (vectorsFor(length / 3 + 1) + 1) * kLanes; }

NBTF_SIMD_CLONES void split(const float* __restrict x, int length, int stride, float* __restrict phases) {
  float* __restrict p0 = phases;
  float* __restrict p1 = phases + stride;
  float* __restrict p2 = phases + 2 * stride;
  const int pooled = length / 3;
  p0[0] = 0;
  for (int p = 0; p < pooled; ++p) {
    p1[p] = x[3 * p];
    p2[p] = x[3 * p + 1];
    p0[p + 1] = x[3 * p + 2];
  }
  p1[pooled] = 3 * pooled < length ? x[3 * pooled] : 0.0f;
  p2[pooled] = 3 * pooled + 1 < length ? x[3 * pooled + 1] : 0.0f;
  std::fill(p0 + pooled + 1, p0 + stride, 0.0f);
  std::fill(p1 + pooled + 1, p1 + stride, 0.0f);
  std::fill(p2 + pooled + 1, p2 + stride, 0.0f);
}

namespace {

NBTF_AVX512 void convolveBlocked(const float* src, int srcChannels, int stride, const float* coef, const float* bias,
                                 int dstChannels, int vectors, float* dst, int dstStride) {
  int d = 0;
  for (; d + 8 <= dstChannels; d += 8)
    convolveBlock<8>(src, srcChannels, stride, coef + static_cast<std::ptrdiff_t>(d) * srcChannels * 3,
                     bias ? bias + d : nullptr, vectors, dst + static_cast<std::ptrdiff_t>(d) * 3 * dstStride, dstStride);
  for (; d < dstChannels; d += kChannelBlock)
    convolveBlock<kChannelBlock>(src, srcChannels, stride, coef + static_cast<std::ptrdiff_t>(d) * srcChannels * 3,
                                 bias ? bias + d : nullptr, vectors, dst + static_cast<std::ptrdiff_t>(d) * 3 * dstStride,
                                 dstStride);
}

// The same a row at a time, plain loops for the vectorizer: for CPUs without AVX-512.
NBTF_SIMD_CLONES void convolveRows(const float* src, int srcChannels, int stride, const float* coef, const float* bias,
                                   int dstChannels, int vectors, float* dst, int dstStride) {
  const int n = vectors * kLanes;
  for (int d = 0; d < dstChannels; ++d)
    for (int j = 0; j < 3; ++j) {
      float* __restrict out = dst + static_cast<std::ptrdiff_t>(d * 3 + j) * dstStride;
      std::fill(out, out + n, bias ? bias[d] : 0.0f);
      for (int s = 0; s < srcChannels; ++s) {
        const float* w = coef + (static_cast<std::ptrdiff_t>(d) * srcChannels + s) * 3;
        // Tap t reads phase row (j + t) % 3 at window p + (j + t) / 3.
        const float* rows = src + static_cast<std::ptrdiff_t>(s) * 3 * stride;
        const float* __restrict r0 = rows + j % 3 * stride + j / 3;
        const float* __restrict r1 = rows + (j + 1) % 3 * stride + (j + 1) / 3;
        const float* __restrict r2 = rows + (j + 2) % 3 * stride + (j + 2) / 3;
        const float w0 = w[0], w1 = w[1], w2 = w[2];
        for (int p = 0; p < n; ++p) out[p] += w0 * r0[p] + w1 * r1[p] + w2 * r2[p];
      }
    }
}

}  // namespace

void convolve(const float* src, int srcChannels, int stride, const float* coef, const float* bias, int dstChannels,
              int vectors, float* dst, int dstStride) {
  static const bool blocked = hasAvx512();
  (blocked ? convolveBlocked : convolveRows)(src, srcChannels, stride, coef, bias, dstChannels, vectors, dst, dstStride);
}

// (pool and unpool are plain loops for the vectorizer: with target_clones GCC lowers vector
// comparisons of the vector extension for the baseline target, lane by lane.)
NBTF_SIMD_CLONES void pool(const float* __restrict conv, int stride, int pooled, float* __restrict y,
                           std::uint8_t* __restrict which) {
  const float* r0 = conv;
  const float* r1 = conv + stride;
  const float* r2 = conv + 2 * stride;
  for (int p = 0; p < pooled; ++p) {
    const float v0 = r0[p], v1 = r1[p], v2 = r2[p];
    const bool take1 = v1 > v0 || v1 != v1;
    const float best = take1 ? v1 : v0;
    const bool take2 = v2 > best || v2 != v2;
    y[p] = take2 ? v2 : best;
    which[p] = static_cast<std::uint8_t>(take2 ? 2 : take1 ? 1 : 0);
  }
}

NBTF_SIMD_CLONES float unpool(const float* __restrict gy, const std::uint8_t* __restrict which, int pooled, int stride,
                              float* __restrict phases) {
  float* __restrict r0 = phases + 1;  // row 0 one window later
  float* __restrict r1 = phases + stride;
  float* __restrict r2 = phases + 2 * stride;
  for (int p = 0; p < pooled; ++p) {
    const float g = gy[p];
    const float w = which[p];  // compared as floats: masks as wide as g's lanes vectorize well
    r1[p] = w == 0 ? g : 0.0f;
    r2[p] = w == 1 ? g : 0.0f;
    r0[p] = w == 2 ? g : 0.0f;
  }
  phases[0] = 0;
  std::fill(r0 + pooled, phases + stride, 0.0f);
  std::fill(r1 + pooled, r1 + stride, 0.0f);
  std::fill(r2 + pooled, r2 + stride, 0.0f);
  float acc[kLanes] = {};
  int p = 0;
  for (; p + kLanes <= pooled; p += kLanes)
    for (int k = 0; k < kLanes; ++k) acc[k] += gy[p + k];
  for (; p < pooled; ++p) acc[p % kLanes] += gy[p];
  float sum = 0;
  for (float a : acc) sum += a;
  return sum;
}

NBTF_SIMD_CLONES void merge(const float* __restrict rows, int stride, int length, float* __restrict x) {
  const float* r0 = rows;
  const float* r1 = rows + stride;
  const float* r2 = rows + 2 * stride;
  const int whole = length / 3;
  for (int p = 0; p < whole; ++p) {
    x[3 * p] = r0[p];
    x[3 * p + 1] = r1[p];
    x[3 * p + 2] = r2[p];
  }
  for (int m = 3 * whole; m < length; ++m) x[m] = rows[(m % 3) * stride + whole];
}

NBTF_SIMD_CLONES void weightGradient(const float* g, int outChannels, const float* x, int inChannels, int stride,
                                     int vectors, float* gw) {
  for (int c = 0; c < inChannels; ++c) {
    const float* xc = x + static_cast<std::ptrdiff_t>(c) * 3 * stride;
    for (int o = 0; o < outChannels;) {
      float sums[8 * 3];
      const float* go = g + static_cast<std::ptrdiff_t>(o) * 3 * stride;
      int block = outChannels - o >= 8 ? 8 : kChannelBlock;
      if (block == 8)
        weightGradientBlock<8>(go, xc, stride, vectors, sums);
      else
        weightGradientBlock<kChannelBlock>(go, xc, stride, vectors, sums);
      for (int d = 0; d < block; ++d)
        for (int t = 0; t < 3; ++t) gw[((o + d) * inChannels + c) * 3 + t] = sums[d * 3 + t];
      o += block;
    }
  }
}

}  // namespace nbtf::detail::phases
