// The decoder's evaluation kernels. One generic source, written with GCC/Clang vector
// extensions, is instantiated three times: 4-float vectors in the build's baseline
// instruction set (portable), 8-float vectors inside functions compiled for AVX2+FMA, and
// 16-float vectors inside functions compiled for AVX-512. The helpers are always_inline,
// so each instance is compiled entirely for its own instruction set; which one runs is
// decided at run time (CPUID), so one binary runs everywhere and uses what the CPU has.
//
// Hidden layers are register-blocked matrix products: a block of R samples x C vectors
// of outputs lives in registers while the kernel streams the layer's transposed weights
// row by row (one broadcast activation times C weight vectors per row and sample). Every
// output is accumulated in the same order (bias, then inputs 0..in-1, fused multiply-add),
// whatever the blocking, so a sample's result never depends on which tile or block it
// was evaluated in.
#include "codec/decoder_kernels.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "util/error.h"

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wpsabi"  // vector arguments only cross always_inline calls
#endif

#if defined(__x86_64__) || defined(__i386__)
#define NBTF_DECODER_X86 1
#endif

namespace nbtf::detail {
namespace {

#define NBTF_INLINE inline __attribute__((always_inline))

// Loads and stores go through memcpy, so data need not be vector-aligned.
typedef float VecF4 __attribute__((vector_size(16)));
typedef float VecF8 __attribute__((vector_size(32)));
typedef float VecF16 __attribute__((vector_size(64)));
typedef std::int32_t VecI4 __attribute__((vector_size(16)));
typedef std::int32_t VecI8 __attribute__((vector_size(32)));
typedef std::int32_t VecI16 __attribute__((vector_size(64)));

template <class V> struct VecInfo;
template <> struct VecInfo<VecF4> { using Int = VecI4; static constexpr int kLanes = 4; };
template <> struct VecInfo<VecF8> { using Int = VecI8; static constexpr int kLanes = 8; };
template <> struct VecInfo<VecF16> { using Int = VecI16; static constexpr int kLanes = 16; };

template <class V> NBTF_INLINE V load(const float* p) {
  V v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
template <class V> NBTF_INLINE void store(float* p, const V& v) { std::memcpy(p, &v, sizeof v); }
template <class V> NBTF_INLINE V relu(const V& v) {
  using I = typename VecInfo<V>::Int;
  return reinterpret_cast<V>(reinterpret_cast<I>(v) & reinterpret_cast<I>(v > V{}));
}
// Pairwise (tree) sum of the lanes.
template <class V> NBTF_INLINE float horizontalSum(const V& v) {
  constexpr int L = VecInfo<V>::kLanes;
  float t[L];
  std::memcpy(t, &v, sizeof v);
#pragma GCC unroll 4
  for (int w = L / 2; w >= 1; w /= 2)
#pragma GCC unroll 8
    for (int i = 0; i < w; ++i) t[i] += t[i + w];
  return t[0];
}

NBTF_INLINE float sigmoid(float x) { return 1.0f / (1.0f + std::exp(-x)); }

// ---- First layer ------------------------------------------------------------------

// b0 + W0_z z for one latent row.
template <class V> NBTF_INLINE void latentPart(const PackedDecoder& p, int row, float* dst) {
  constexpr int L = VecInfo<V>::kLanes;
  const float* z = p.latents + static_cast<std::size_t>(row) * p.latentDim;
  for (int j = 0; j < p.pad0; j += L) {
    V acc = load<V>(p.bias0.data() + j);
    for (int q = 0; q < p.latentDim; ++q) acc += z[q] * load<V>(p.latentWeights.data() + static_cast<std::size_t>(q) * p.pad0 + j);
    store(dst + j, acc);
  }
}

// W0_dir [l; v] for one (light, view). Queries with their own directions pay this per
// sample, so four output vectors are summed side by side: one vector at a time is a chain of
// dirInputs dependent FMAs that waits on their latency (with the 28 Fourier inputs that was
// about as slow as all the hidden layers). Each output still sums its inputs in the same
// order, so the values are the same bits.
template <class V> NBTF_INLINE void directionPart(const PackedDecoder& p, const float* d, float* dst) {
  constexpr int L = VecInfo<V>::kLanes;
  int j = 0;
  for (; j + 4 * L <= p.pad0; j += 4 * L) {
    V a0{}, a1{}, a2{}, a3{};
    for (int q = 0; q < p.dirInputs; ++q) {
      const float* w = p.dirWeights.data() + static_cast<std::size_t>(q) * p.pad0 + j;
      a0 += d[q] * load<V>(w);
      a1 += d[q] * load<V>(w + L);
      a2 += d[q] * load<V>(w + 2 * L);
      a3 += d[q] * load<V>(w + 3 * L);
    }
    store(dst + j, a0), store(dst + j + L, a1), store(dst + j + 2 * L, a2), store(dst + j + 3 * L, a3);
  }
  for (; j < p.pad0; j += L) {
    V acc{};
    for (int q = 0; q < p.dirInputs; ++q) acc += d[q] * load<V>(p.dirWeights.data() + static_cast<std::size_t>(q) * p.pad0 + j);
    store(dst + j, acc);
  }
}

// ---- Dense layers -----------------------------------------------------------------

// out[R x C vectors] = act(bias + in[R x K] * w[K x C vectors]).
template <class V, int R, int C>
NBTF_INLINE void denseBlock(const float* in, int inStride, int k, const float* w, int wStride, const float* bias,
                            float* out, int outStride, bool applyRelu) {
  constexpr int L = VecInfo<V>::kLanes;
  V acc[R][C];
#pragma GCC unroll 8
  for (int c = 0; c < C; ++c) {
    V b = load<V>(bias + L * c);
#pragma GCC unroll 8
    for (int r = 0; r < R; ++r) acc[r][c] = b;
  }
  for (int i = 0; i < k; ++i) {
    const float* wi = w + static_cast<std::size_t>(i) * wStride;
    V wv[C];
#pragma GCC unroll 8
    for (int c = 0; c < C; ++c) wv[c] = load<V>(wi + L * c);
#pragma GCC unroll 8
    for (int r = 0; r < R; ++r) {
      const float s = in[static_cast<std::size_t>(r) * inStride + i];
#pragma GCC unroll 8
      for (int c = 0; c < C; ++c) acc[r][c] += s * wv[c];
    }
  }
#pragma GCC unroll 8
  for (int r = 0; r < R; ++r)
#pragma GCC unroll 8
    for (int c = 0; c < C; ++c) store(out + static_cast<std::size_t>(r) * outStride + L * c, applyRelu ? relu(acc[r][c]) : acc[r][c]);
}

template <class V, int R, int C>
NBTF_INLINE void densePanel(const float* in, int inStride, int rows, const PackedLayer& layer, int col, float* out,
                            int outStride, bool applyRelu) {
  for (int r = 0; r < rows; r += R)
    denseBlock<V, R, C>(in + static_cast<std::size_t>(r) * inStride, inStride, layer.in, layer.weights.data() + col,
                        layer.outPad, layer.bias.data() + col, out + static_cast<std::size_t>(r) * outStride + col,
                        outStride, applyRelu);
}

// Block shapes per vector width: R samples x C output vectors, with R x C accumulators
// plus C weight vectors and a broadcast fitting the register file (32 vector registers
// with AVX-512, 16 otherwise). Rows per block divide kRowGranule.
struct Blocking16 {  // AVX-512
  static constexpr int kMaxCols = 4;
  static constexpr int rowsFor(int c) { return c == 4 ? 6 : 8; }
};
struct Blocking8 {  // AVX2, and the portable 4-float build
  static constexpr int kMaxCols = 3;
  static constexpr int rowsFor(int c) { return c == 3 ? 4 : c == 2 ? 6 : 8; }
};

template <class V, class B>
NBTF_INLINE void denseLayer(const float* in, int inStride, int rows, const PackedLayer& layer, float* out) {
  constexpr int L = VecInfo<V>::kLanes;
  const int vectors = layer.outPad / L;
  const bool applyRelu = layer.activation == Activation::Relu;
  for (int c0 = 0; c0 < vectors;) {
    int c = std::min(B::kMaxCols, vectors - c0);
    int col = c0 * L;
    switch (c) {
      case 4:
        if constexpr (B::kMaxCols >= 4) densePanel<V, B::rowsFor(4), 4>(in, inStride, rows, layer, col, out, layer.outPad, applyRelu);
        break;
      case 3: densePanel<V, B::rowsFor(3), 3>(in, inStride, rows, layer, col, out, layer.outPad, applyRelu); break;
      case 2: densePanel<V, B::rowsFor(2), 2>(in, inStride, rows, layer, col, out, layer.outPad, applyRelu); break;
      default: densePanel<V, B::rowsFor(1), 1>(in, inStride, rows, layer, col, out, layer.outPad, applyRelu); break;
    }
    c0 += c;
  }
  if (layer.activation == Activation::Sigmoid)
    for (int r = 0; r < rows; ++r)
      for (int j = 0; j < layer.out; ++j) {
        float& v = out[static_cast<std::size_t>(r) * layer.outPad + j];
        v = sigmoid(v);
      }
}

// ---- Output layer: a few outputs, so dot products over the (padded) inputs ------------

template <class V>
NBTF_INLINE void outputLayer(const float* in, int inStride, int n, const PackedLayer& layer, float* out) {
  constexpr int L = VecInfo<V>::kLanes;
  const int chunks = layer.inPad / L;
  for (int s = 0; s < n; ++s) {
    const float* h = in + static_cast<std::size_t>(s) * inStride;
    for (int o0 = 0; o0 < layer.out; o0 += 4) {
      const int count = std::min(4, layer.out - o0);
      V acc[4] = {};
      for (int c = 0; c < chunks; ++c) {
        V hv = load<V>(h + c * L);
#pragma GCC unroll 4
        for (int o = 0; o < 4; ++o)
          if (o < count) acc[o] += hv * load<V>(layer.weights.data() + static_cast<std::size_t>(o0 + o) * layer.inPad + c * L);
      }
      for (int o = 0; o < count; ++o) {
        float v = horizontalSum(acc[o]) + layer.bias[o0 + o];
        if (layer.activation == Activation::Relu) v = std::max(v, 0.0f);
        else if (layer.activation == Activation::Sigmoid) v = sigmoid(v);
        out[static_cast<std::size_t>(s) * layer.out + o0 + o] = v;
      }
    }
  }
}

// ---- One tile -----------------------------------------------------------------------

template <class V, class B> NBTF_INLINE void evaluateTile(const PackedDecoder& p, const TileArgs& a) {
  constexpr int L = VecInfo<V>::kLanes;
  // Whole row blocks: the rows past n repeat the last sample and are not written out.
  const int rows = padTo(a.n, kRowGranule);
  float* bufA = a.scratch;
  float* bufB = bufA + static_cast<std::size_t>(kTileRows) * p.maxPad;
  float* dirBuf = bufB + static_cast<std::size_t>(kTileRows) * p.maxPad;
  float* rowBuf = dirBuf + p.pad0;
  const bool relu0 = p.activation0 == Activation::Relu;

  // The first-layer rows of a per-texel material (texels x 112 floats) outgrow the
  // caches and queries hit them at random: request the tile's rows before using any.
  if (a.prefetchRows && !p.rowPart.empty()) {
    for (int s = 0; s < a.n; ++s) {
      const float* part = p.rowPart.data() + static_cast<std::size_t>(a.rows[s]) * p.pad0;
      for (int j = 0; j < p.pad0; j += 64 / static_cast<int>(sizeof(float))) __builtin_prefetch(part + j);
    }
  }
  const float* lastDirs = nullptr;
  for (int s = 0; s < rows; ++s) {
    const int src = std::min(s, a.n - 1);
    const float* d = a.dirs + static_cast<std::size_t>(src) * a.dirStride;
    if (d != lastDirs && (!lastDirs || std::memcmp(d, lastDirs, p.dirInputs * sizeof(float)) != 0)) directionPart<V>(p, d, dirBuf);
    lastDirs = d;
    const int row = a.rows[src];
    const float* part;
    if (!p.rowPart.empty()) {
      part = p.rowPart.data() + static_cast<std::size_t>(row) * p.pad0;
    } else {
      latentPart<V>(p, row, rowBuf);
      part = rowBuf;
    }
    float* h = bufA + static_cast<std::size_t>(s) * p.pad0;
    for (int j = 0; j < p.pad0; j += L) {
      V v = load<V>(part + j) + load<V>(dirBuf + j);
      store(h + j, relu0 ? relu(v) : v);
    }
    if (p.activation0 == Activation::Sigmoid)
      for (int j = 0; j < p.width0; ++j) h[j] = sigmoid(h[j]);
  }
  if (p.singleLayer) {
    for (int s = 0; s < a.n; ++s)
      for (int o = 0; o < p.outputs; ++o) a.out[static_cast<std::size_t>(s) * p.outputs + o] = bufA[static_cast<std::size_t>(s) * p.pad0 + o];
    return;
  }
  float* cur = bufA;
  float* next = bufB;
  int stride = p.pad0;
  for (const PackedLayer& layer : p.hidden) {
    denseLayer<V, B>(cur, stride, rows, layer, next);
    std::swap(cur, next);
    stride = layer.outPad;
  }
  outputLayer<V>(cur, stride, a.n, p.output, a.out);
}

template <class V> NBTF_INLINE void latentParts(const PackedDecoder& p, int begin, int end, float* rowPart) {
  for (int r = begin; r < end; ++r) latentPart<V>(p, r, rowPart + static_cast<std::size_t>(r) * p.pad0);
}

// ---- The instances ------------------------------------------------------------------------

// Fused multiply-add wherever the target has it: the kernels are written as a * b + c.
#if defined(__clang__)
#define NBTF_FMA_CONTRACT
#pragma clang fp contract(fast)
#else
#define NBTF_FMA_CONTRACT optimize("fp-contract=fast")
#endif

__attribute__((NBTF_FMA_CONTRACT)) void tilePortable(const PackedDecoder& p, const TileArgs& a) {
  evaluateTile<VecF4, Blocking8>(p, a);
}
__attribute__((NBTF_FMA_CONTRACT)) void latentPartsPortable(const PackedDecoder& p, int b, int e, float* out) {
  latentParts<VecF4>(p, b, e, out);
}

#ifdef NBTF_DECODER_X86
__attribute__((target("avx2,fma"), NBTF_FMA_CONTRACT)) void tileAvx2(const PackedDecoder& p, const TileArgs& a) {
  evaluateTile<VecF8, Blocking8>(p, a);
}
__attribute__((target("avx2,fma"), NBTF_FMA_CONTRACT)) void latentPartsAvx2(const PackedDecoder& p, int b, int e,
                                                                            float* out) {
  latentParts<VecF8>(p, b, e, out);
}
__attribute__((target("avx512f,avx512vl,avx2,fma"), NBTF_FMA_CONTRACT)) void tileAvx512(const PackedDecoder& p,
                                                                                         const TileArgs& a) {
  evaluateTile<VecF16, Blocking16>(p, a);
}
__attribute__((target("avx512f,avx512vl,avx2,fma"), NBTF_FMA_CONTRACT)) void latentPartsAvx512(
    const PackedDecoder& p, int b, int e, float* out) {
  latentParts<VecF16>(p, b, e, out);
}
#endif

// ---- Packing ------------------------------------------------------------------------------

PackedLayer packDense(const DenseLayer& l, int inPad) {
  PackedLayer p;
  p.in = l.in, p.out = l.out, p.inPad = inPad, p.outPad = padTo(l.out, kPadFloats);
  p.activation = l.activation;
  p.weights.assign(static_cast<std::size_t>(l.in) * p.outPad, 0.0f);
  p.bias.assign(p.outPad, 0.0f);
  for (int o = 0; o < l.out; ++o) {
    p.bias[o] = l.bias[o];
    for (int i = 0; i < l.in; ++i)
      p.weights[static_cast<std::size_t>(i) * p.outPad + o] = l.weight[static_cast<std::size_t>(o) * l.in + i];
  }
  return p;
}

PackedLayer packOutput(const DenseLayer& l, int inPad) {
  PackedLayer p;
  p.in = l.in, p.out = l.out, p.inPad = inPad, p.outPad = l.out;
  p.activation = l.activation;
  p.weights.assign(static_cast<std::size_t>(l.out) * inPad, 0.0f);
  for (int o = 0; o < l.out; ++o)
    std::copy_n(l.weight.data() + static_cast<std::size_t>(o) * l.in, l.in, p.weights.data() + static_cast<std::size_t>(o) * inPad);
  p.bias.assign(l.bias.begin(), l.bias.end());
  return p;
}

}  // namespace

PackedDecoder packDecoder(const Mlp& mlp, int latentDim, int dirInputs) {
  if (mlp.layers.empty()) throw Error("decoder has no layers");
  const DenseLayer& first = mlp.layers.front();
  if (first.in != latentDim + dirInputs || dirInputs < 1 || dirInputs > kMaxDecoderDirectionInputs)
    throw Error("decoder takes " + std::to_string(first.in) + " inputs, expected latent " + std::to_string(latentDim) +
                " + " + std::to_string(dirInputs) + " direction inputs");
  PackedDecoder p;
  p.dirInputs = dirInputs;
  p.latentDim = latentDim;
  p.outputs = mlp.layers.back().out;
  p.width0 = first.out;
  p.pad0 = padTo(first.out, kPadFloats);
  p.activation0 = first.activation;
  p.bias0.assign(p.pad0, 0.0f);
  p.latentWeights.assign(static_cast<std::size_t>(latentDim) * p.pad0, 0.0f);
  p.dirWeights.assign(static_cast<std::size_t>(dirInputs) * p.pad0, 0.0f);
  for (int o = 0; o < first.out; ++o) {
    p.bias0[o] = first.bias[o];
    const float* w = first.weight.data() + static_cast<std::size_t>(o) * first.in;
    for (int q = 0; q < latentDim; ++q) p.latentWeights[static_cast<std::size_t>(q) * p.pad0 + o] = w[q];
    for (int q = 0; q < dirInputs; ++q) p.dirWeights[static_cast<std::size_t>(q) * p.pad0 + o] = w[latentDim + q];
  }
  p.maxPad = p.pad0;
  p.singleLayer = mlp.layers.size() == 1;
  int inPad = p.pad0;
  for (std::size_t i = 1; i < mlp.layers.size(); ++i) {
    if (i + 1 < mlp.layers.size()) {
      p.hidden.push_back(packDense(mlp.layers[i], inPad));
      inPad = p.hidden.back().outPad;
      p.maxPad = std::max(p.maxPad, inPad);
    } else {
      p.output = packOutput(mlp.layers[i], inPad);
    }
  }
  return p;
}

DecoderIsa bestSupportedIsa() {
  if (decoderIsaSupported(DecoderIsa::Avx512)) return DecoderIsa::Avx512;
  if (decoderIsaSupported(DecoderIsa::Avx2)) return DecoderIsa::Avx2;
  return DecoderIsa::Portable;
}

KernelSet kernelsFor(DecoderIsa isa) {
  switch (isa) {
#ifdef NBTF_DECODER_X86
    case DecoderIsa::Avx512: return {tileAvx512, latentPartsAvx512};
    case DecoderIsa::Avx2: return {tileAvx2, latentPartsAvx2};
#endif
    case DecoderIsa::Portable: return {tilePortable, latentPartsPortable};
    default: throw Error("decoder kernels for '" + decoderIsaName(isa) + "' are not available in this build");
  }
}

}  // namespace nbtf::detail

namespace nbtf {

bool decoderIsaSupported(DecoderIsa isa) {
  switch (isa) {
    case DecoderIsa::Auto:
    case DecoderIsa::Portable: return true;
#ifdef NBTF_DECODER_X86
    case DecoderIsa::Avx2: return hasAvx2Fma();
    case DecoderIsa::Avx512: return hasAvx512Vl() && hasAvx2Fma();
#endif
    default: return false;
  }
}

}  // namespace nbtf
