// Internal to the decoder (codec/decoder.cpp): the decoder MLP repacked for evaluation and
// the SIMD kernels that evaluate it, one tile of samples at a time. Not a public header.
//
// Packing: every layer's outputs are padded to a multiple of kPadFloats with zero weights
// and biases, so activations are whole SIMD vectors and the padding stays exactly 0
// (ReLU(0) = 0, identity(0) = 0; sigmoid layers re-zero it). Hidden layers are stored
// transposed (in x outPad, one row per input), which is the order the register-blocked
// kernel streams them in. The first layer is split (see decoder.h): the latent part
// b0 + W0_z z is per latent row, the direction part W0_dir [l; v] per (light, view).
#pragma once
#include <cstddef>
#include <cstdint>
#include <new>
#include <vector>

#include "codec/decoder.h"
#include "codec/mlp.h"
#include "util/simd.h"

namespace nbtf::detail {

constexpr int kPadFloats = 16;  // one AVX-512 vector
// Samples per tile: the kernels' row blocks (3, 4, 6 or 8 samples) all divide 24, and a
// tile of 48 keeps two layers of activations (48 x 112 floats each) in L1/L2.
constexpr int kTileRows = 48;
constexpr int kRowGranule = 24;

inline int padTo(int n, int m) { return (n + m - 1) / m * m; }

struct PackedLayer {
  int in = 0, out = 0;
  int inPad = 0, outPad = 0;
  Activation activation = Activation::None;
  // Dense layers: in x outPad (transposed). The output layer: out x inPad (row-major),
  // evaluated as dot products.
  AlignedFloats weights;
  AlignedFloats bias;  // outPad (dense) or out (output layer)
};

struct PackedDecoder {
  int latentDim = 0;
  int outputs = 3;
  // ---- First layer (layer 0)
  int width0 = 0, pad0 = 0;
  Activation activation0 = Activation::None;
  AlignedFloats bias0;          // pad0
  AlignedFloats latentWeights;  // latentDim x pad0 (transposed W0_z)
  int dirInputs = 4;            // direction inputs per sample (util/directions.h)
  AlignedFloats dirWeights;     // dirInputs x pad0 (transposed W0_dir)
  const float* latents = nullptr;  // rows x latentDim (the material's), for uncached rows
  AlignedFloats rowPart;        // rows x pad0: b0 + W0_z z, or empty = computed per sample
  // ---- Layers 1 .. L-2 (dense) and L-1 (the output layer); none when L == 1.
  std::vector<PackedLayer> hidden;
  PackedLayer output;
  bool singleLayer = false;          // L == 1: layer 0 is the output layer
  int maxPad = 0;                    // widest padded activation

  // Floats of scratch one tile evaluation needs.
  std::size_t scratchFloats() const {
    return 2 * static_cast<std::size_t>(kTileRows) * maxPad + 2 * static_cast<std::size_t>(pad0) + kPadFloats;
  }
};

// Repacks `mlp` (validated: input latentDim + dirInputs).
PackedDecoder packDecoder(const Mlp& mlp, int latentDim, int dirInputs);

// One tile: n <= kTileRows samples, each a latent row and dirInputs direction inputs
// (dirStride = dirInputs; dirStride 0 = every sample shares the first ones). Writes n x outputs decoder outputs
// (normalized, not x alpha). Consecutive samples with equal directions share one
// direction-part computation, so the result never depends on how samples are grouped.
struct TileArgs {
  const std::int32_t* rows = nullptr;
  const float* dirs = nullptr;
  int dirStride = 4;
  int n = 0;
  bool prefetchRows = false;  // rows in random order (queries): prefetch their first-layer parts
  float* out = nullptr;
  float* scratch = nullptr;  // scratchFloats() floats, 64-byte aligned
};
using TileKernel = void (*)(const PackedDecoder&, const TileArgs&);
// rowPart[i] = b0 + W0_z z_i for rows [begin, end), pad0 floats each.
using RowPartKernel = void (*)(const PackedDecoder&, int begin, int end, float* rowPart);

struct KernelSet {
  TileKernel tile = nullptr;
  RowPartKernel rowPart = nullptr;
};
// The kernels for `isa` (which must be supported; Auto is resolved by the caller).
KernelSet kernelsFor(DecoderIsa isa);
DecoderIsa bestSupportedIsa();

}  // namespace nbtf::detail
