#include "model/kernels/dense_kernels.h"

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <type_traits>

#include "util/simd.h"

// The vector type below is passed between inlined helpers only; GCC's note that its ABI
// differs without AVX-512 does not concern us.
#pragma GCC diagnostic ignored "-Wpsabi"

namespace nbtf::detail {
namespace {

// Three builds of every kernel, by CPU:
//   Wide   (AVX-512): 16-float vectors (one zmm each), panels of 4 vectors, 32 registers;
//   Mid    (AVX2 + FMA): 8-float vectors (one ymm each), panels of 2 vectors, 16 registers;
//   Narrow (anything else, and clang or sanitizer builds): 16-float vectors in panels of one,
//          two rows per block, so nothing spills whatever the target splits a vector into.
// Each sums in the same index order; results differ between builds only by FMA rounding.
enum class Tier { Narrow, Mid, Wide };

// GCC/clang vector extensions. Loads and stores go through memcpy (no alignment or aliasing
// assumptions); the compiler turns them into plain vector moves.
using Vec16 = float __attribute__((vector_size(16 * sizeof(float))));
using Vec8 = float __attribute__((vector_size(8 * sizeof(float))));
template <Tier T> using VecOf = std::conditional_t<T == Tier::Mid, Vec8, Vec16>;
template <Tier T> constexpr int kLanes = static_cast<int>(sizeof(VecOf<T>) / sizeof(float));

template <class V> inline __attribute__((always_inline)) V load(const float* p) {
  V v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
template <class V> inline __attribute__((always_inline)) void store(float* p, V v) { std::memcpy(p, &v, sizeof v); }

// Vectors per column panel. Wide: 4 (64 floats); with 6 rows that is 24 accumulators, plus
// the 4 row vectors of b and a broadcast, within the 32 registers. Measured against 7 vectors
// x 3 rows (the decoder's whole 112-float row at once): about 1.3x faster, as each loaded
// value feeds more FMAs. Mid: 2 (16 floats) x 6 rows = 12 accumulators + 2 + 1 of 16.
template <Tier T> constexpr int panelVectors() { return T == Tier::Wide ? 4 : T == Tier::Mid ? 2 : 1; }

// Rows (or gradient rows) per register block for a panel of V vectors.
template <int V, Tier T>
constexpr int blockRows() {
  if constexpr (T == Tier::Narrow) return 2;
  if constexpr (T == Tier::Mid) return V == 2 ? 6 : 12;
  return V == 4 ? 6 : V == 3 ? 8 : V == 2 ? 12 : 16;
}

enum class Epilogue { None, Relu, Mask };

// R rows x V vectors of y (+)= x[:, q0:q1] b[q0:q1, :]: the first slice of the sum starts
// from zero, later ones from y; the last applies the epilogue.
template <Tier T, int R, int V, Epilogue E>
inline __attribute__((always_inline)) void productBlock(int q0, int q1, bool first, bool last, const float* x,
                                                        int ldx, const float* b, int cols, float* y, const float* h) {
  using Vec = VecOf<T>;
  constexpr int L = kLanes<T>;
  Vec acc[R][V];
  for (int r = 0; r < R; ++r)
    for (int v = 0; v < V; ++v)
      acc[r][v] = first ? Vec{} : load<Vec>(y + static_cast<std::size_t>(r) * cols + L * v);
  for (int q = q0; q < q1; ++q) {
    Vec w[V];
    for (int v = 0; v < V; ++v) w[v] = load<Vec>(b + static_cast<std::size_t>(q) * cols + L * v);
    for (int r = 0; r < R; ++r) {
      const float s = x[static_cast<std::size_t>(r) * ldx + q];
      for (int v = 0; v < V; ++v) acc[r][v] += s * w[v];
    }
  }
  const Vec zero = {};
  for (int r = 0; r < R; ++r)
    for (int v = 0; v < V; ++v) {
      float* out = y + static_cast<std::size_t>(r) * cols + L * v;
      if (!last || E == Epilogue::None) {
        store(out, acc[r][v]);
      } else if constexpr (E == Epilogue::Relu) {
        store(out, acc[r][v] > zero ? acc[r][v] : zero);
      } else {
        const Vec mask = load<Vec>(h + static_cast<std::size_t>(r) * cols + L * v);
        store(out, mask > zero ? acc[r][v] : zero);
      }
    }
}

// The sum over q in slices of at most kSliceDepth rows of b (a panel), so a slice of b stays
// in L1 while every row block of x passes over it; rows in blocks of R (R x V accumulators fit
// the registers), the rest one by one. Each y entry still sums q in increasing order.
constexpr int kSliceDepth = 48;

template <int V, Epilogue E, Tier T>
inline __attribute__((always_inline)) void productPanel(int n, int k, const float* x, int ldx, const float* b,
                                                        int cols, float* y, const float* h) {
  constexpr int R = blockRows<V, T>();
  const int slices = std::max(1, (k + kSliceDepth - 1) / kSliceDepth), depth = std::max(1, (k + slices - 1) / slices);
  for (int q0 = 0; q0 < std::max(k, 1); q0 += depth) {
    const int q1 = std::min(k, q0 + depth);
    const bool first = q0 == 0, last = q1 >= k;
    int r = 0;
    for (; r + R <= n; r += R) {
      const std::size_t off = static_cast<std::size_t>(r) * cols;
      productBlock<T, R, V, E>(q0, q1, first, last, x + static_cast<std::size_t>(r) * ldx, ldx, b, cols, y + off,
                               h ? h + off : nullptr);
    }
    for (; r < n; ++r) {
      const std::size_t off = static_cast<std::size_t>(r) * cols;
      productBlock<T, 1, V, E>(q0, q1, first, last, x + static_cast<std::size_t>(r) * ldx, ldx, b, cols, y + off,
                               h ? h + off : nullptr);
    }
  }
}

template <Epilogue E, Tier T>
inline __attribute__((always_inline)) void productOf(int n, int k, const float* x, int ldx, const float* b, int cols,
                                                   float* y, const float* h) {
  // Column panels: b, y and h are addressed from the panel's first column, strides unchanged.
  constexpr int panel = panelVectors<T>(), L = kLanes<T>;
  for (int c0 = 0; c0 < cols; c0 += panel * L) {
    const float* bp = b + c0;
    float* yp = y + c0;
    const float* hp = h ? h + c0 : nullptr;
    switch (std::min(panel, (cols - c0) / L)) {
      case 4: if constexpr (panel >= 4) productPanel<4, E, T>(n, k, x, ldx, bp, cols, yp, hp); break;
      case 3: if constexpr (panel >= 3) productPanel<3, E, T>(n, k, x, ldx, bp, cols, yp, hp); break;
      case 2: if constexpr (panel >= 2) productPanel<2, E, T>(n, k, x, ldx, bp, cols, yp, hp); break;
      default: productPanel<1, E, T>(n, k, x, ldx, bp, cols, yp, hp); break;
    }
  }
}

// M rows of w (gradient rows i0 .. i0 + M) x V vectors, summed over rows r0 .. r1 of g and h.
template <Tier T, int M, int V>
inline __attribute__((always_inline)) void outerBlock(int r0, int r1, const float* g, int ldg, const float* h,
                                                      int cols, float* w) {
  using Vec = VecOf<T>;
  constexpr int L = kLanes<T>;
  Vec acc[M][V];
  for (int i = 0; i < M; ++i)
    for (int v = 0; v < V; ++v) acc[i][v] = load<Vec>(w + static_cast<std::size_t>(i) * cols + L * v);
  for (int r = r0; r < r1; ++r) {
    Vec hv[V];
    for (int v = 0; v < V; ++v) hv[v] = load<Vec>(h + static_cast<std::size_t>(r) * cols + L * v);
    for (int i = 0; i < M; ++i) {
      const float s = g[static_cast<std::size_t>(r) * ldg + i];
      for (int v = 0; v < V; ++v) acc[i][v] += s * hv[v];
    }
  }
  for (int i = 0; i < M; ++i)
    for (int v = 0; v < V; ++v) store(w + static_cast<std::size_t>(i) * cols + L * v, acc[i][v]);
}

template <int V, Tier T>
inline __attribute__((always_inline)) void outerPanel(int r0, int r1, int m, const float* g, int ldg, const float* h,
                                                      int cols, float* w) {
  constexpr int M = blockRows<V, T>();
  int i = 0;
  for (; i + M <= m; i += M) outerBlock<T, M, V>(r0, r1, g + i, ldg, h, cols, w + static_cast<std::size_t>(i) * cols);
  for (; i < m; ++i) outerBlock<T, 1, V>(r0, r1, g + i, ldg, h, cols, w + static_cast<std::size_t>(i) * cols);
}

template <Tier T>
inline __attribute__((always_inline)) void outer(int n, int m, const float* g, int ldg, const float* h, int cols,
                                                 float* w) {
  // Rows in slices of 32, so a slice of g and h (2 x 32 x 112 floats) stays in L1 while
  // every block of gradient rows passes over it. Each w entry still sums r in order.
  constexpr int kSliceRows = 32, panel = panelVectors<T>(), L = kLanes<T>;
  for (int r0 = 0; r0 < n; r0 += kSliceRows) {
    const int r1 = std::min(n, r0 + kSliceRows);
    for (int c0 = 0; c0 < cols; c0 += panel * L) {
      const float* hp = h + c0;
      float* wp = w + c0;
      switch (std::min(panel, (cols - c0) / L)) {
        case 4: if constexpr (panel >= 4) outerPanel<4, T>(r0, r1, m, g, ldg, hp, cols, wp); break;
        case 3: if constexpr (panel >= 3) outerPanel<3, T>(r0, r1, m, g, ldg, hp, cols, wp); break;
        case 2: if constexpr (panel >= 2) outerPanel<2, T>(r0, r1, m, g, ldg, hp, cols, wp); break;
        default: outerPanel<1, T>(r0, r1, m, g, ldg, hp, cols, wp); break;
      }
    }
  }
}

// ---- The three builds of each kernel.
NBTF_AVX512 void productReluWide(int n, int k, const float* x, int ldx, const float* b, int cols, float* y) {
  productOf<Epilogue::Relu, Tier::Wide>(n, k, x, ldx, b, cols, y, nullptr);
}
NBTF_AVX2_FMA void productReluMid(int n, int k, const float* x, int ldx, const float* b, int cols, float* y) {
  productOf<Epilogue::Relu, Tier::Mid>(n, k, x, ldx, b, cols, y, nullptr);
}
NBTF_SIMD_CLONES void productReluNarrow(int n, int k, const float* x, int ldx, const float* b, int cols, float* y) {
  productOf<Epilogue::Relu, Tier::Narrow>(n, k, x, ldx, b, cols, y, nullptr);
}
NBTF_AVX512 void productPlainWide(int n, int k, const float* x, int ldx, const float* b, int cols, float* y) {
  productOf<Epilogue::None, Tier::Wide>(n, k, x, ldx, b, cols, y, nullptr);
}
NBTF_AVX2_FMA void productPlainMid(int n, int k, const float* x, int ldx, const float* b, int cols, float* y) {
  productOf<Epilogue::None, Tier::Mid>(n, k, x, ldx, b, cols, y, nullptr);
}
NBTF_SIMD_CLONES void productPlainNarrow(int n, int k, const float* x, int ldx, const float* b, int cols, float* y) {
  productOf<Epilogue::None, Tier::Narrow>(n, k, x, ldx, b, cols, y, nullptr);
}
NBTF_AVX512 void productMaskedWide(int n, int k, const float* x, int ldx, const float* b, int cols, const float* h,
                                   float* y) {
  productOf<Epilogue::Mask, Tier::Wide>(n, k, x, ldx, b, cols, y, h);
}
NBTF_AVX2_FMA void productMaskedMid(int n, int k, const float* x, int ldx, const float* b, int cols, const float* h,
                                    float* y) {
  productOf<Epilogue::Mask, Tier::Mid>(n, k, x, ldx, b, cols, y, h);
}
NBTF_SIMD_CLONES void productMaskedNarrow(int n, int k, const float* x, int ldx, const float* b, int cols,
                                          const float* h, float* y) {
  productOf<Epilogue::Mask, Tier::Narrow>(n, k, x, ldx, b, cols, y, h);
}
NBTF_AVX512 void outerWide(int n, int m, const float* g, int ldg, const float* h, int cols, float* w) {
  outer<Tier::Wide>(n, m, g, ldg, h, cols, w);
}
NBTF_AVX2_FMA void outerMid(int n, int m, const float* g, int ldg, const float* h, int cols, float* w) {
  outer<Tier::Mid>(n, m, g, ldg, h, cols, w);
}
NBTF_SIMD_CLONES void outerNarrow(int n, int m, const float* g, int ldg, const float* h, int cols, float* w) {
  outer<Tier::Narrow>(n, m, g, ldg, h, cols, w);
}

DenseKernelTier forced = DenseKernelTier::Auto;  // setDenseKernelTier
Tier tier() {
  static const Tier best = hasAvx512() ? Tier::Wide : hasAvx2Fma() ? Tier::Mid : Tier::Narrow;
  switch (forced) {
    case DenseKernelTier::Narrow: return Tier::Narrow;
    case DenseKernelTier::Mid: return Tier::Mid;
    case DenseKernelTier::Wide: return Tier::Wide;
    default: return best;
  }
}

}  // namespace

bool denseKernelTierSupported(DenseKernelTier t) {
  switch (t) {
    case DenseKernelTier::Wide: return hasAvx512();
    case DenseKernelTier::Mid: return hasAvx2Fma();
    default: return true;
  }
}

void setDenseKernelTier(DenseKernelTier t) {
  if (!denseKernelTierSupported(t)) throw std::invalid_argument("dense kernels: this CPU cannot run that tier");
  forced = t;
}

void productRelu(int n, int k, const float* x, int ldx, const float* b, int cols, float* y) {
  switch (tier()) {
    case Tier::Wide: return productReluWide(n, k, x, ldx, b, cols, y);
    case Tier::Mid: return productReluMid(n, k, x, ldx, b, cols, y);
    default: return productReluNarrow(n, k, x, ldx, b, cols, y);
  }
}

void product(int n, int k, const float* x, int ldx, const float* b, int cols, float* y) {
  switch (tier()) {
    case Tier::Wide: return productPlainWide(n, k, x, ldx, b, cols, y);
    case Tier::Mid: return productPlainMid(n, k, x, ldx, b, cols, y);
    default: return productPlainNarrow(n, k, x, ldx, b, cols, y);
  }
}

void productMasked(int n, int k, const float* x, int ldx, const float* b, int cols, const float* h, float* y) {
  switch (tier()) {
    case Tier::Wide: return productMaskedWide(n, k, x, ldx, b, cols, h, y);
    case Tier::Mid: return productMaskedMid(n, k, x, ldx, b, cols, h, y);
    default: return productMaskedNarrow(n, k, x, ldx, b, cols, h, y);
  }
}

void accumulateOuter(int n, int m, const float* g, int ldg, const float* h, int cols, float* w) {
  switch (tier()) {
    case Tier::Wide: return outerWide(n, m, g, ldg, h, cols, w);
    case Tier::Mid: return outerMid(n, m, g, ldg, h, cols, w);
    default: return outerNarrow(n, m, g, ldg, h, cols, w);
  }
}

NBTF_SIMD_CLONES void rowDots(int n, int m, const float* h, int cols, const float* w, float* out) {
  for (int r = 0; r < n; ++r) {
    const float* hr = h + static_cast<std::size_t>(r) * cols;
    for (int i = 0; i < m; ++i) {
      const float* wi = w + static_cast<std::size_t>(i) * cols;
      Vec16 acc = {};
      for (int c = 0; c < cols; c += kDenseLanes) acc += load<Vec16>(hr + c) * load<Vec16>(wi + c);
      float s = 0;
      for (int l = 0; l < kDenseLanes; ++l) s += acc[l];
      out[static_cast<std::size_t>(r) * m + i] = s;
    }
  }
}

}  // namespace nbtf::detail
