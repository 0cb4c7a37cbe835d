// Products of bfloat16 operands with float sums (dense_kernels.h): the AVX-512 BF16 build
// (register blocks as in dense_kernels.cpp, each VDPBF16PS two terms of the sum) and a
// portable build that takes the same steps in float.
#include <algorithm>
#include <cstring>
#include <vector>

#include "model/kernels/dense_kernels.h"

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_ADDRESS__)
#include <immintrin.h>
#define NBTF_HAVE_BF16_BUILD 1
#define NBTF_BF16 __attribute__((target("avx512f,avx512bw,avx512vl,avx512bf16")))
#define NBTF_BF16_INLINE __attribute__((target("avx512f,avx512bw,avx512vl,avx512bf16"), always_inline)) inline
#endif

namespace nbtf::detail {

namespace {

// Branch-free, so that the conversion loops vectorize: the bits of VCVTNE2PS2BF16.
inline Bf16 roundToBf16(float value) {
  std::uint32_t u;
  std::memcpy(&u, &value, sizeof u);
  const std::uint32_t zero = (u >> 16) & 0x8000u;                    // zero, subnormal: signed zero
  const std::uint32_t nearest = (u + 0x7fffu + ((u >> 16) & 1u)) >> 16;  // nearest, ties even
  const std::uint32_t nan = (u >> 16) | 0x0040u;                     // NaN stays (quiet) NaN
  std::uint32_t r = (u & 0x7f800000u) == 0 ? zero : nearest;
  r = (u & 0x7fffffffu) > 0x7f800000u ? nan : r;
  return static_cast<Bf16>(r);
}

NBTF_SIMD_CLONES void rowsPortable(int n, int cols, const float* src, int lds, Bf16* dst, int ldd) {
  for (int r = 0; r < n; ++r) {
    const float* __restrict s = src + static_cast<std::size_t>(r) * lds;
    Bf16* __restrict d = dst + static_cast<std::size_t>(r) * ldd;
    for (int j = 0; j < cols; ++j) d[j] = roundToBf16(s[j]);
    std::fill(d + cols, d + ldd, Bf16{0});
  }
}

NBTF_SIMD_CLONES void rowPairsPortable(int n, int cols, const float* src, int lds, Bf16* dst) {
  for (int r = 0; r < n; r += 2) {
    const float* __restrict a = src + static_cast<std::size_t>(r) * lds;
    const float* __restrict b = r + 1 < n ? a + lds : nullptr;
    Bf16* __restrict d = dst + static_cast<std::size_t>(r / 2) * cols * 2;
    for (int j = 0; j < cols; ++j) {
      d[2 * j] = roundToBf16(a[j]);
      d[2 * j + 1] = b ? roundToBf16(b[j]) : Bf16{0};
    }
  }
}

}  // namespace

Bf16 toBf16(float value) { return roundToBf16(value); }

float fromBf16(Bf16 value) {
  const std::uint32_t u = static_cast<std::uint32_t>(value) << 16;
  float f;
  std::memcpy(&f, &u, sizeof f);
  return f;
}

namespace {

bool forcePortable = false;  // setBf16ProductsPortable

// ---- Portable build: float steps in the instruction's order (odd term, then even term).
NBTF_SIMD_CLONES void productPortable(Bf16Epilogue e, int n, int k, const Bf16* x, int ldx, const Bf16* b, int cols,
                                      const float* h, float* y) {
  std::vector<float> acc(cols);
  for (int r = 0; r < n; ++r) {
    std::fill(acc.begin(), acc.end(), 0.0f);
    const Bf16* xr = x + static_cast<std::size_t>(r) * ldx;
    for (int p = 0; p < k / 2; ++p) {
      const float xe = fromBf16(xr[2 * p]), xo = fromBf16(xr[2 * p + 1]);
      const Bf16* bp = b + static_cast<std::size_t>(p) * cols * 2;
      for (int j = 0; j < cols; ++j) {
        acc[j] += xo * fromBf16(bp[2 * j + 1]);
        acc[j] += xe * fromBf16(bp[2 * j]);
      }
    }
    float* yr = y + static_cast<std::size_t>(r) * cols;
    const float* hr = h ? h + static_cast<std::size_t>(r) * cols : nullptr;
    for (int j = 0; j < cols; ++j)
      yr[j] = e == Bf16Epilogue::Relu ? std::max(acc[j], 0.0f) : e == Bf16Epilogue::Mask ? (hr[j] > 0 ? acc[j] : 0.0f) : acc[j];
  }
}

NBTF_SIMD_CLONES void outerPortable(int n, int m, const Bf16* g, int ldg, const Bf16* h, int cols, float* w) {
  for (int p = 0; p < (n + 1) / 2; ++p) {
    const Bf16* gp = g + static_cast<std::size_t>(p) * ldg * 2;
    const Bf16* hp = h + static_cast<std::size_t>(p) * cols * 2;
    for (int i = 0; i < m; ++i) {
      const float ge = fromBf16(gp[2 * i]), go = fromBf16(gp[2 * i + 1]);
      float* wi = w + static_cast<std::size_t>(i) * cols;
      for (int j = 0; j < cols; ++j) {
        float s = wi[j];
        s += go * fromBf16(hp[2 * j + 1]);
        s += ge * fromBf16(hp[2 * j]);
        wi[j] = s;
      }
    }
  }
}

#ifdef NBTF_HAVE_BF16_BUILD
// ---- AVX-512 BF16 build. 16 float lanes per vector, each lane fed a pair of terms.
NBTF_BF16_INLINE __m512bh broadcastPair(const Bf16* p) {
  std::int32_t v;
  std::memcpy(&v, p, sizeof v);
  return (__m512bh)_mm512_set1_epi32(v);
}
NBTF_BF16_INLINE __m512bh loadPairs(const Bf16* p) { return (__m512bh)_mm512_loadu_si512(p); }

// R rows x V vectors of y = x b (pairs p0 .. p1 of the sum) with the epilogue. The whole sum
// in one pass: the decoder's k (at most 128) keeps a 4-vector panel of b (64 columns x 64
// pairs x 4 bytes) in L1 while every row block passes over it.
template <int R, int V>
NBTF_BF16_INLINE void productBlockBf16(Bf16Epilogue e, int pairs, const Bf16* x, int ldx, const Bf16* b, int cols,
                                       const float* h, float* y) {
  __m512 acc[R][V];
  for (int r = 0; r < R; ++r)
    for (int v = 0; v < V; ++v) acc[r][v] = _mm512_setzero_ps();
  for (int p = 0; p < pairs; ++p) {
    __m512bh w[V];
    for (int v = 0; v < V; ++v) w[v] = loadPairs(b + (static_cast<std::size_t>(p) * cols + 16 * v) * 2);
    for (int r = 0; r < R; ++r) {
      const __m512bh s = broadcastPair(x + static_cast<std::size_t>(r) * ldx + 2 * p);
      for (int v = 0; v < V; ++v) acc[r][v] = _mm512_dpbf16_ps(acc[r][v], s, w[v]);
    }
  }
  const __m512 zero = _mm512_setzero_ps();
  for (int r = 0; r < R; ++r)
    for (int v = 0; v < V; ++v) {
      float* out = y + static_cast<std::size_t>(r) * cols + 16 * v;
      __m512 value = acc[r][v];
      if (e == Bf16Epilogue::Relu) value = _mm512_maskz_mov_ps(_mm512_cmp_ps_mask(value, zero, _CMP_GT_OQ), value);
      if (e == Bf16Epilogue::Mask) {
        const __mmask16 live = _mm512_cmp_ps_mask(_mm512_loadu_ps(h + static_cast<std::size_t>(r) * cols + 16 * v), zero, _CMP_GT_OQ);
        value = _mm512_maskz_mov_ps(live, value);
      }
      _mm512_storeu_ps(out, value);
    }
}

template <int V>
NBTF_BF16_INLINE void productPanelBf16(Bf16Epilogue e, int n, int pairs, const Bf16* x, int ldx, const Bf16* b, int cols,
                                       const float* h, float* y) {
  constexpr int R = V == 4 ? 6 : V == 3 ? 8 : V == 2 ? 12 : 16;
  int r = 0;
  for (; r + R <= n; r += R) {
    const std::size_t off = static_cast<std::size_t>(r) * cols;
    productBlockBf16<R, V>(e, pairs, x + static_cast<std::size_t>(r) * ldx, ldx, b, cols, h ? h + off : nullptr, y + off);
  }
  for (; r < n; ++r) {
    const std::size_t off = static_cast<std::size_t>(r) * cols;
    productBlockBf16<1, V>(e, pairs, x + static_cast<std::size_t>(r) * ldx, ldx, b, cols, h ? h + off : nullptr, y + off);
  }
}

NBTF_BF16 void productNative(Bf16Epilogue e, int n, int k, const Bf16* x, int ldx, const Bf16* b, int cols,
                             const float* h, float* y) {
  for (int c0 = 0; c0 < cols; c0 += 64) {
    const Bf16* bp = b + static_cast<std::size_t>(c0) * 2;
    const float* hp = h ? h + c0 : nullptr;
    switch (std::min(4, (cols - c0) / 16)) {
      case 4: productPanelBf16<4>(e, n, k / 2, x, ldx, bp, cols, hp, y + c0); break;
      case 3: productPanelBf16<3>(e, n, k / 2, x, ldx, bp, cols, hp, y + c0); break;
      case 2: productPanelBf16<2>(e, n, k / 2, x, ldx, bp, cols, hp, y + c0); break;
      default: productPanelBf16<1>(e, n, k / 2, x, ldx, bp, cols, hp, y + c0); break;
    }
  }
}

// M gradient rows x V vectors of w, summed over pairs p0 .. p1 of the rows of g and h.
template <int M, int V>
NBTF_BF16_INLINE void outerBlockBf16(int p0, int p1, const Bf16* g, int ldg, const Bf16* h, int cols, float* w) {
  __m512 acc[M][V];
  for (int i = 0; i < M; ++i)
    for (int v = 0; v < V; ++v) acc[i][v] = _mm512_loadu_ps(w + static_cast<std::size_t>(i) * cols + 16 * v);
  for (int p = p0; p < p1; ++p) {
    __m512bh hv[V];
    for (int v = 0; v < V; ++v) hv[v] = loadPairs(h + (static_cast<std::size_t>(p) * cols + 16 * v) * 2);
    for (int i = 0; i < M; ++i) {
      const __m512bh s = broadcastPair(g + (static_cast<std::size_t>(p) * ldg + i) * 2);
      for (int v = 0; v < V; ++v) acc[i][v] = _mm512_dpbf16_ps(acc[i][v], s, hv[v]);
    }
  }
  for (int i = 0; i < M; ++i)
    for (int v = 0; v < V; ++v) _mm512_storeu_ps(w + static_cast<std::size_t>(i) * cols + 16 * v, acc[i][v]);
}

template <int V>
NBTF_BF16_INLINE void outerPanelBf16(int p0, int p1, int m, const Bf16* g, int ldg, const Bf16* h, int cols, float* w) {
  constexpr int M = V == 4 ? 6 : V == 3 ? 8 : V == 2 ? 12 : 16;
  int i = 0;
  for (; i + M <= m; i += M) outerBlockBf16<M, V>(p0, p1, g + 2 * i, ldg, h, cols, w + static_cast<std::size_t>(i) * cols);
  for (; i < m; ++i) outerBlockBf16<1, V>(p0, p1, g + 2 * i, ldg, h, cols, w + static_cast<std::size_t>(i) * cols);
}

NBTF_BF16 void outerNative(int n, int m, const Bf16* g, int ldg, const Bf16* h, int cols, float* w) {
  // Row pairs in slices of 16 (32 rows), so a slice of g and h stays in L1 while every block
  // of gradient rows passes over it; each w entry still sums the pairs in order.
  constexpr int kSlicePairs = 16;
  const int pairs = (n + 1) / 2;
  for (int p0 = 0; p0 < pairs; p0 += kSlicePairs) {
    const int p1 = std::min(pairs, p0 + kSlicePairs);
    for (int c0 = 0; c0 < cols; c0 += 64) {
      const Bf16* hp = h + static_cast<std::size_t>(c0) * 2;
      float* wp = w + c0;
      switch (std::min(4, (cols - c0) / 16)) {
        case 4: outerPanelBf16<4>(p0, p1, m, g, ldg, hp, cols, wp); break;
        case 3: outerPanelBf16<3>(p0, p1, m, g, ldg, hp, cols, wp); break;
        case 2: outerPanelBf16<2>(p0, p1, m, g, ldg, hp, cols, wp); break;
        default: outerPanelBf16<1>(p0, p1, m, g, ldg, hp, cols, wp); break;
      }
    }
  }
}

// Conversions by VCVTNE2PS2BF16 (the same bits as roundToBf16), 16 columns at a time.
NBTF_BF16_INLINE __mmask16 tailMask(int left) { return left >= 16 ? 0xffff : static_cast<__mmask16>((1u << left) - 1); }

NBTF_BF16 void rowsNative(int n, int cols, const float* src, int lds, Bf16* dst, int ldd) {
  for (int r = 0; r < n; ++r) {
    const float* s = src + static_cast<std::size_t>(r) * lds;
    Bf16* d = dst + static_cast<std::size_t>(r) * ldd;
    int j = 0;
    for (; j < cols; j += 16) {
      const __mmask16 m = tailMask(cols - j);
      const __m256i v = (__m256i)_mm512_cvtneps_pbh(_mm512_maskz_loadu_ps(m, s + j));
      _mm256_mask_storeu_epi16(d + j, m, v);
    }
    std::fill(d + cols, d + ldd, Bf16{0});
  }
}

NBTF_BF16 void rowPairsNative(int n, int cols, const float* src, int lds, Bf16* dst) {
  // Lanes 0..15 the first row's 16 values, 16..31 the second's; interleave them.
  const __m512i interleave = _mm512_set_epi16(31, 15, 30, 14, 29, 13, 28, 12, 27, 11, 26, 10, 25, 9, 24, 8, 23, 7, 22, 6,
                                              21, 5, 20, 4, 19, 3, 18, 2, 17, 1, 16, 0);
  for (int r = 0; r < n; r += 2) {
    const float* a = src + static_cast<std::size_t>(r) * lds;
    const float* b = a + lds;
    const bool second = r + 1 < n;
    Bf16* d = dst + static_cast<std::size_t>(r / 2) * cols * 2;
    for (int j = 0; j < cols; j += 16) {
      const __mmask16 m = tailMask(cols - j);
      const __m512 va = _mm512_maskz_loadu_ps(m, a + j);
      const __m512 vb = second ? _mm512_maskz_loadu_ps(m, b + j) : _mm512_setzero_ps();
      const __m512i both = _mm512_permutexvar_epi16(interleave, (__m512i)_mm512_cvtne2ps_pbh(vb, va));
      const __mmask32 m2 = cols - j >= 16 ? 0xffffffffu : static_cast<__mmask32>((1ull << (2 * (cols - j))) - 1);
      _mm512_mask_storeu_epi16(d + 2 * j, m2, both);
    }
  }
}
#endif

bool useNative() { return bf16ProductsNative() && !forcePortable; }

}  // namespace

bool bf16ProductsNative() {
#ifdef NBTF_HAVE_BF16_BUILD
  static const bool native = __builtin_cpu_supports("avx512bf16") && __builtin_cpu_supports("avx512bw") &&
                             __builtin_cpu_supports("avx512vl");
  return native;
#else
  return false;
#endif
}

void setBf16ProductsPortable(bool portable) { forcePortable = portable; }

void toBf16Rows(int n, int cols, const float* src, int lds, Bf16* dst, int ldd) {
#ifdef NBTF_HAVE_BF16_BUILD
  if (useNative()) return rowsNative(n, cols, src, lds, dst, ldd);
#endif
  rowsPortable(n, cols, src, lds, dst, ldd);
}

void toBf16RowPairs(int n, int cols, const float* src, int lds, Bf16* dst) {
#ifdef NBTF_HAVE_BF16_BUILD
  if (useNative()) return rowPairsNative(n, cols, src, lds, dst);
#endif
  rowPairsPortable(n, cols, src, lds, dst);
}

void productBf16(Bf16Epilogue epilogue, int n, int k, const Bf16* x, int ldx, const Bf16* bPairs, int cols,
                 const float* h, float* y) {
#ifdef NBTF_HAVE_BF16_BUILD
  if (useNative()) return productNative(epilogue, n, k, x, ldx, bPairs, cols, h, y);
#endif
  productPortable(epilogue, n, k, x, ldx, bPairs, cols, h, y);
}

void accumulateOuterBf16(int n, int m, const Bf16* gPairs, int ldg, const Bf16* hPairs, int cols, float* w) {
#ifdef NBTF_HAVE_BF16_BUILD
  if (useNative()) return outerNative(n, m, gPairs, ldg, hPairs, cols, w);
#endif
  outerPortable(n, m, gPairs, ldg, hPairs, cols, w);
}

}  // namespace nbtf::detail
