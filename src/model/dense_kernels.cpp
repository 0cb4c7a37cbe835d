#include "model/dense_kernels.h"

#include <algorithm>
#include <cstring>

#include "util/simd.h"

// The vector type below is passed between inlined helpers only; GCC's note that its ABI
// differs without AVX-512 does not concern us.
#pragma GCC diagnostic ignored "-Wpsabi"

namespace nbtf::detail {
namespace {

// A 16-float vector (GCC/clang vector extension): one zmm register in the AVX-512 clone,
// two ymm or four xmm in the others. Loads and stores go through memcpy (no alignment or
// aliasing assumptions); the compiler turns them into plain vector moves.
using Vec = float __attribute__((vector_size(kDenseLanes * sizeof(float))));

inline __attribute__((always_inline)) Vec load(const float* p) {
  Vec v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline __attribute__((always_inline)) void store(float* p, Vec v) { std::memcpy(p, &v, sizeof v); }

// Columns per panel: 4 vectors (64 floats); with 6 rows that is 24 accumulators, plus the 4
// row vectors of b and a broadcast, within the 32 vector registers. Measured against 7
// vectors x 3 rows (the decoder's whole 112-float row at once): about 1.3x faster, as each
// loaded value feeds more FMAs.
constexpr int kPanelVectors = 4;

// Rows (or gradient rows) per register block for a panel of V vectors. With Wide false
// (CPUs without AVX-512, where a 16-float vector takes 2 or 4 registers of 16) panels are
// one vector and blocks two rows, so nothing spills.
template <int V, bool Wide>
constexpr int blockRows() {
  if constexpr (!Wide) return 2;
  return V == 4 ? 6 : V == 3 ? 8 : V == 2 ? 12 : 16;
}

enum class Epilogue { Relu, Mask };

// R rows x V vectors of y (+)= x[:, q0:q1] b[q0:q1, :]: the first slice of the sum starts
// from zero, later ones from y; the last applies the epilogue.
template <int R, int V, Epilogue E>
inline __attribute__((always_inline)) void productBlock(int q0, int q1, bool first, bool last, const float* x,
                                                        int ldx, const float* b, int cols, float* y, const float* h) {
  Vec acc[R][V];
  for (int r = 0; r < R; ++r)
    for (int v = 0; v < V; ++v)
      acc[r][v] = first ? Vec{} : load(y + static_cast<std::size_t>(r) * cols + kDenseLanes * v);
  for (int q = q0; q < q1; ++q) {
    Vec w[V];
    for (int v = 0; v < V; ++v) w[v] = load(b + static_cast<std::size_t>(q) * cols + kDenseLanes * v);
    for (int r = 0; r < R; ++r) {
      const float s = x[static_cast<std::size_t>(r) * ldx + q];
      for (int v = 0; v < V; ++v) acc[r][v] += s * w[v];
    }
  }
  const Vec zero = {};
  for (int r = 0; r < R; ++r)
    for (int v = 0; v < V; ++v) {
      float* out = y + static_cast<std::size_t>(r) * cols + kDenseLanes * v;
      if (!last) {
        store(out, acc[r][v]);
      } else if constexpr (E == Epilogue::Relu) {
        store(out, acc[r][v] > zero ? acc[r][v] : zero);
      } else {
        const Vec mask = load(h + static_cast<std::size_t>(r) * cols + kDenseLanes * v);
        store(out, mask > zero ? acc[r][v] : zero);
      }
    }
}

// The sum over q in slices of at most kSliceDepth rows of b (a panel: 4 x 16 floats each), so a
// slice of b stays in L1 while every row block of x passes over it; rows in blocks of R
// (R x V accumulators fit the registers), the rest one by one. Each y entry still sums q
// in increasing order.
constexpr int kSliceDepth = 48;

template <int V, Epilogue E, bool Wide>
inline __attribute__((always_inline)) void productPanel(int n, int k, const float* x, int ldx, const float* b,
                                                        int cols, float* y, const float* h) {
  constexpr int R = blockRows<V, Wide>();
  const int slices = std::max(1, (k + kSliceDepth - 1) / kSliceDepth), depth = std::max(1, (k + slices - 1) / slices);
  for (int q0 = 0; q0 < std::max(k, 1); q0 += depth) {
    const int q1 = std::min(k, q0 + depth);
    const bool first = q0 == 0, last = q1 >= k;
    int r = 0;
    for (; r + R <= n; r += R) {
      const std::size_t off = static_cast<std::size_t>(r) * cols;
      productBlock<R, V, E>(q0, q1, first, last, x + static_cast<std::size_t>(r) * ldx, ldx, b, cols, y + off,
                            h ? h + off : nullptr);
    }
    for (; r < n; ++r) {
      const std::size_t off = static_cast<std::size_t>(r) * cols;
      productBlock<1, V, E>(q0, q1, first, last, x + static_cast<std::size_t>(r) * ldx, ldx, b, cols, y + off,
                            h ? h + off : nullptr);
    }
  }
}

template <Epilogue E, bool Wide>
inline __attribute__((always_inline)) void product(int n, int k, const float* x, int ldx, const float* b, int cols,
                                                   float* y, const float* h) {
  // Column panels: b, y and h are addressed from the panel's first column, strides unchanged.
  constexpr int panel = Wide ? kPanelVectors : 1;
  for (int c0 = 0; c0 < cols; c0 += panel * kDenseLanes) {
    const float* bp = b + c0;
    float* yp = y + c0;
    const float* hp = h ? h + c0 : nullptr;
    switch (std::min(panel, (cols - c0) / kDenseLanes)) {
      case 4: productPanel<4, E, Wide>(n, k, x, ldx, bp, cols, yp, hp); break;
      case 3: productPanel<3, E, Wide>(n, k, x, ldx, bp, cols, yp, hp); break;
      case 2: productPanel<2, E, Wide>(n, k, x, ldx, bp, cols, yp, hp); break;
      default: productPanel<1, E, Wide>(n, k, x, ldx, bp, cols, yp, hp); break;
    }
  }
}

// M rows of w (gradient rows i0 .. i0 + M) x V vectors, summed over rows r0 .. r1 of g and h.
template <int M, int V>
inline __attribute__((always_inline)) void outerBlock(int r0, int r1, const float* g, int ldg, const float* h,
                                                      int cols, float* w) {
  Vec acc[M][V];
  for (int i = 0; i < M; ++i)
    for (int v = 0; v < V; ++v) acc[i][v] = load(w + static_cast<std::size_t>(i) * cols + kDenseLanes * v);
  for (int r = r0; r < r1; ++r) {
    Vec hv[V];
    for (int v = 0; v < V; ++v) hv[v] = load(h + static_cast<std::size_t>(r) * cols + kDenseLanes * v);
    for (int i = 0; i < M; ++i) {
      const float s = g[static_cast<std::size_t>(r) * ldg + i];
      for (int v = 0; v < V; ++v) acc[i][v] += s * hv[v];
    }
  }
  for (int i = 0; i < M; ++i)
    for (int v = 0; v < V; ++v) store(w + static_cast<std::size_t>(i) * cols + kDenseLanes * v, acc[i][v]);
}

template <int V, bool Wide>
inline __attribute__((always_inline)) void outerPanel(int r0, int r1, int m, const float* g, int ldg, const float* h,
                                                      int cols, float* w) {
  constexpr int M = blockRows<V, Wide>();
  int i = 0;
  for (; i + M <= m; i += M) outerBlock<M, V>(r0, r1, g + i, ldg, h, cols, w + static_cast<std::size_t>(i) * cols);
  for (; i < m; ++i) outerBlock<1, V>(r0, r1, g + i, ldg, h, cols, w + static_cast<std::size_t>(i) * cols);
}

template <bool Wide>
inline __attribute__((always_inline)) void outer(int n, int m, const float* g, int ldg, const float* h, int cols,
                                                 float* w) {
  // Rows in slices of 32, so a slice of g and h (2 x 32 x 112 floats) stays in L1 while
  // every block of gradient rows passes over it. Each w entry still sums r in order.
  constexpr int kSliceRows = 32, panel = Wide ? kPanelVectors : 1;
  for (int r0 = 0; r0 < n; r0 += kSliceRows) {
    const int r1 = std::min(n, r0 + kSliceRows);
    for (int c0 = 0; c0 < cols; c0 += panel * kDenseLanes) {
      const float* hp = h + c0;
      float* wp = w + c0;
      switch (std::min(panel, (cols - c0) / kDenseLanes)) {
        case 4: outerPanel<4, Wide>(r0, r1, m, g, ldg, hp, cols, wp); break;
        case 3: outerPanel<3, Wide>(r0, r1, m, g, ldg, hp, cols, wp); break;
        case 2: outerPanel<2, Wide>(r0, r1, m, g, ldg, hp, cols, wp); break;
        default: outerPanel<1, Wide>(r0, r1, m, g, ldg, hp, cols, wp); break;
      }
    }
  }
}

// ---- The two builds of each kernel: AVX-512 register blocks, and the narrow blocks that
// every other target (and clang or sanitizer builds) runs.
NBTF_AVX512 void productReluWide(int n, int k, const float* x, int ldx, const float* b, int cols, float* y) {
  product<Epilogue::Relu, true>(n, k, x, ldx, b, cols, y, nullptr);
}
NBTF_SIMD_CLONES void productReluNarrow(int n, int k, const float* x, int ldx, const float* b, int cols, float* y) {
  product<Epilogue::Relu, false>(n, k, x, ldx, b, cols, y, nullptr);
}
NBTF_AVX512 void productMaskedWide(int n, int k, const float* x, int ldx, const float* b, int cols, const float* h,
                                   float* y) {
  product<Epilogue::Mask, true>(n, k, x, ldx, b, cols, y, h);
}
NBTF_SIMD_CLONES void productMaskedNarrow(int n, int k, const float* x, int ldx, const float* b, int cols,
                                          const float* h, float* y) {
  product<Epilogue::Mask, false>(n, k, x, ldx, b, cols, y, h);
}
NBTF_AVX512 void outerWide(int n, int m, const float* g, int ldg, const float* h, int cols, float* w) {
  outer<true>(n, m, g, ldg, h, cols, w);
}
NBTF_SIMD_CLONES void outerNarrow(int n, int m, const float* g, int ldg, const float* h, int cols, float* w) {
  outer<false>(n, m, g, ldg, h, cols, w);
}

bool genericOnly = false;  // setDenseKernelsGeneric
bool wide() {
  static const bool avx512 = hasAvx512();
  return avx512 && !genericOnly;
}

}  // namespace

void setDenseKernelsGeneric(bool generic) { genericOnly = generic; }

void productRelu(int n, int k, const float* x, int ldx, const float* b, int cols, float* y) {
  if (wide()) productReluWide(n, k, x, ldx, b, cols, y);
  else productReluNarrow(n, k, x, ldx, b, cols, y);
}

void productMasked(int n, int k, const float* x, int ldx, const float* b, int cols, const float* h, float* y) {
  if (wide()) productMaskedWide(n, k, x, ldx, b, cols, h, y);
  else productMaskedNarrow(n, k, x, ldx, b, cols, h, y);
}

void accumulateOuter(int n, int m, const float* g, int ldg, const float* h, int cols, float* w) {
  if (wide()) outerWide(n, m, g, ldg, h, cols, w);
  else outerNarrow(n, m, g, ldg, h, cols, w);
}

NBTF_SIMD_CLONES void rowDots(int n, int m, const float* h, int cols, const float* w, float* out) {
  for (int r = 0; r < n; ++r) {
    const float* hr = h + static_cast<std::size_t>(r) * cols;
    for (int i = 0; i < m; ++i) {
      const float* wi = w + static_cast<std::size_t>(i) * cols;
      Vec acc = {};
      for (int c = 0; c < cols; c += kDenseLanes) acc += load(hr + c) * load(wi + c);
      float s = 0;
      for (int l = 0; l < kDenseLanes; ++l) s += acc[l];
      out[static_cast<std::size_t>(r) * m + i] = s;
    }
  }
}

}  // namespace nbtf::detail
