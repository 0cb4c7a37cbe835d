// The decoder MLP's evaluator, for both neural kinds: the network packed once (the per-row half
// of the first layer cached), samples evaluated in tiles by the SIMD kernels
// (codec/decoder_kernels.h), per-texel modulation mixed in after each tile.
#include <algorithm>
#include <functional>

#include "codec/decoder_kernels.h"
#include "codec/methods/evaluator.h"
#include "codec/methods/neural.h"
#include "util/parallel.h"

namespace nbtf {
namespace {

using detail::kMinParallelSamples;
using detail::kTileRows;

// Per-thread scratch, so evaluations allocate nothing after the first.
float* threadScratch(std::size_t floats) {
  thread_local AlignedFloats scratch;
  if (scratch.size() < floats) scratch.resize(floats);
  return scratch.data();
}

using CombineFn = std::function<void(const float*, const std::int32_t*, int, float*)>;
// n samples' terms -> RGB with their texels' coefficients; empty without modulation.
CombineFn combinerOf(const NbtfDecoder& d) {
  if (!d.modulated()) return {};
  return [&d](const float* terms, const std::int32_t* texels, int n, float* rgb) {
    const int r = d.modulationTerms(), channels = d.modulationChannels();
    for (int i = 0; i < n; ++i)
      detail::combineTerms(d.texelCoefficients().data() + static_cast<std::size_t>(texels[i]) * r * channels,
                           terms + static_cast<std::size_t>(i) * 3 * r, r, channels, rgb + 3 * i);
  };
}

using FillFn = std::function<void(std::size_t, int, std::int32_t*, float*, std::int32_t*)>;

// Runs `count` samples in tiles, in parallel when worth it. fill(begin, n, rows, dirs, texels)
// writes the latent rows, direction inputs and texels of samples [begin, begin + n). With
// `combine` (modulated materials) the tile's terms go to a buffer and combine(terms, texels,
// n, rgb) mixes them per texel.
void runTiles(const detail::PackedDecoder& packed, detail::TileKernel tile, std::size_t count, float* rgb, float alpha,
              OutputScale scale, const FillFn& fill, const CombineFn& combine) {
  const std::size_t tiles = (count + kTileRows - 1) / kTileRows;
  auto body = [&](std::size_t tileBegin, std::size_t tileEnd) {
    float* scratch = threadScratch(packed.scratchFloats());
    std::int32_t rows[kTileRows], texels[kTileRows];
    float dirs[kMaxDecoderDirectionInputs * kTileRows];
    float terms[3 * kMaxModulationTerms * kTileRows];
    for (std::size_t t = tileBegin; t < tileEnd; ++t) {
      std::size_t begin = t * kTileRows;
      detail::TileArgs a;
      a.n = static_cast<int>(std::min<std::size_t>(kTileRows, count - begin));
      fill(begin, a.n, rows, dirs, texels);
      a.rows = rows;
      a.dirs = dirs;
      a.dirStride = packed.dirInputs;
      a.prefetchRows = true;
      float* out = rgb + 3 * begin;
      a.out = combine ? terms : out;
      a.scratch = scratch;
      tile(packed, a);
      if (combine) combine(terms, texels, a.n, out);
      if (scale == OutputScale::Linear)
        for (int i = 0; i < 3 * a.n; ++i) out[i] *= alpha;
    }
  };
  if (count >= kMinParallelSamples) parallelFor(tiles, body, 8);
  else body(0, tiles);
}

class NeuralEvaluator final : public detail::MaterialEvaluator {
 public:
  NeuralEvaluator(const CompressedBtf& m, DecoderIsa isa, const DecoderOptions& options)
      : packed_(detail::packDecoder(m.decoder, m.latentDim, m.directionInputs())), kernels_(detail::kernelsFor(isa)) {
    packed_.latents = m.latents.data();
    for (const DenseLayer& l : m.decoder.layers) flops_ += 2.0 * l.in * l.out;
    // The per-row half of the first layer, once, with the same kernel the evaluation uses
    // (so cached and uncached rows give identical results).
    const std::size_t bytes = static_cast<std::size_t>(m.latentRows) * packed_.pad0 * sizeof(float);
    if (bytes > options.maxCachedFirstLayerBytes) return;
    packed_.rowPart.assign(static_cast<std::size_t>(m.latentRows) * packed_.pad0, 0.0f);
    parallelFor(
        static_cast<std::size_t>(m.latentRows),
        [&](std::size_t b, std::size_t e) {
          kernels_.rowPart(packed_, static_cast<int>(b), static_cast<int>(e), packed_.rowPart.data());
        },
        4096);
  }

  double flopsPerEvaluation() const override { return flops_; }

  void evaluate(const NbtfDecoder& d, const TexelQuery* queries, std::size_t count, float* rgb,
                OutputScale scale) const override {
    const CompressedBtf& m = d.material();
    const bool clusterPlanes = !m.clusterPlanes.empty();
    const int width = packed_.dirInputs;
    runTiles(packed_, kernels_.tile, count, rgb, m.alpha, scale,
             [&](std::size_t begin, int n, std::int32_t* rows, float* dirs, std::int32_t* texels) {
               // Consecutive queries often share directions: convert each distinct pair once.
               const TexelQuery* last = nullptr;
               DirectionInput input{};
               float points[6];  // the pair's plane points, for cluster planes
               for (int i = 0; i < n; ++i) {
                 const TexelQuery& q = queries[begin + i];
                 texels[i] = q.y * m.width + q.x;
                 rows[i] = m.latentRowOfTexel(texels[i]);
                 if (!last || !(q.light == last->light) || !(q.view == last->view)) {
                   input = decoderDirectionInput(m, q.light, q.view), last = &q;
                   if (clusterPlanes) directionPlanePoints(q.light.unitVector(), q.view.unitVector(), points);
                 }
                 float* slot = dirs + static_cast<std::size_t>(width) * i;
                 std::copy_n(input.data(), width, slot);
                 if (clusterPlanes) addClusterPlaneFeatures(m, rows[i], points, slot);
               }
             },
             combinerOf(d));
  }

  void evaluate(const NbtfDecoder& d, const UvQuery* queries, std::size_t count, float* rgb,
                OutputScale scale) const override {
    const CompressedBtf& m = d.material();
    const int width = packed_.dirInputs;
    runTiles(packed_, kernels_.tile, count, rgb, m.alpha, scale,
             [&](std::size_t begin, int n, std::int32_t* rows, float* dirs, std::int32_t* texels) {
               for (int i = 0; i < n; ++i) {
                 const UvQuery& q = queries[begin + i];
                 texels[i] = d.texelOfUv(q.u, q.v);
                 rows[i] = m.latentRowOfTexel(texels[i]);
                 const auto l = unitQueryVector(q.light, "light"), v = unitQueryVector(q.view, "view");
                 float* slot = dirs + static_cast<std::size_t>(width) * i;
                 decoderDirectionInput(m, l, v, slot);
                 addClusterPlaneFeatures(m, rows[i], l, v, slot);
               }
             },
             combinerOf(d));
  }

  void decodeRows(const NbtfDecoder& d, const Direction& light, const Direction& view, float* rgb, OutputScale scale,
                  bool parallel) const override {
    decodeRowTerms(d, light, view, rgb, parallel);
    if (scale == OutputScale::Linear)
      for (std::size_t i = 0, n = 3 * static_cast<std::size_t>(d.latentRows()); i < n; ++i) rgb[i] *= d.alpha();
  }

  void decodeRowTerms(const NbtfDecoder& d, const Direction& light, const Direction& view, float* out,
                      bool parallel) const override {
    const CompressedBtf& m = d.material();
    const DirectionInput dirs = decoderDirectionInput(m, light, view);
    // With cluster planes every row has direction inputs of its own: written per tile.
    const bool perRow = !m.clusterPlanes.empty();
    float points[6];
    if (perRow) directionPlanePoints(light.unitVector(), view.unitVector(), points);
    const std::size_t count = static_cast<std::size_t>(m.latentRows);
    const std::size_t outputs = static_cast<std::size_t>(packed_.outputs);
    const std::size_t tiles = (count + kTileRows - 1) / kTileRows;
    auto body = [&](std::size_t tileBegin, std::size_t tileEnd) {
      float* scratch = threadScratch(packed_.scratchFloats());
      std::int32_t rows[kTileRows];
      float rowDirs[kMaxDecoderDirectionInputs * kTileRows];
      const int width = packed_.dirInputs;
      for (std::size_t t = tileBegin; t < tileEnd; ++t) {
        std::size_t begin = t * kTileRows;
        detail::TileArgs a;
        a.n = static_cast<int>(std::min<std::size_t>(kTileRows, count - begin));
        for (int i = 0; i < a.n; ++i) rows[i] = static_cast<std::int32_t>(begin + i);
        a.rows = rows;
        a.dirs = dirs.data();
        a.dirStride = 0;  // one direction for the whole image: its first-layer part once per tile
        if (perRow) {
          for (int i = 0; i < a.n; ++i) {
            float* slot = rowDirs + static_cast<std::size_t>(width) * i;
            std::copy_n(dirs.data(), width, slot);
            addClusterPlaneFeatures(m, rows[i], points, slot);
          }
          a.dirs = rowDirs;
          a.dirStride = width;
        }
        a.out = out + outputs * begin;
        a.scratch = scratch;
        kernels_.tile(packed_, a);
      }
    };
    if (parallel && count >= kMinParallelSamples) parallelFor(tiles, body, 8);
    else body(0, tiles);
  }

 private:
  detail::PackedDecoder packed_;
  detail::KernelSet kernels_;
  double flops_ = 0;
};

}  // namespace

std::unique_ptr<detail::MaterialEvaluator> NeuralKind::evaluator(const CompressedBtf& btf, DecoderIsa isa,
                                                                 const DecoderOptions& options) const {
  return std::make_unique<NeuralEvaluator>(btf, isa, options);
}

}  // namespace nbtf
