#include "codec/decoder.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <sstream>

#include "codec/decoder_kernels.h"
#include "codec/pca_model.h"
#include "codec/texel_modulation.h"
#include "util/error.h"
#include "util/parallel.h"

namespace nbtf {
namespace detail {
// The PCA baseline's decoding state: the interpolation over the measured pairs.
struct PcaState {
  DirectionInterpolator interpolator;
};
}  // namespace detail

namespace {

// Batches below this many samples run on the calling thread: starting threads costs more.
constexpr std::size_t kMinParallelSamples = 4096;

// Per-thread scratch, so single evaluations allocate nothing after the first.
float* threadScratch(std::size_t floats) {
  thread_local AlignedFloats scratch;
  if (scratch.size() < floats) scratch.resize(floats);
  return scratch.data();
}

std::string describeTexel(int x, int y) {
  return "texel (" + std::to_string(x) + ", " + std::to_string(y) + ")";
}

}  // namespace

// ---- Instruction sets -------------------------------------------------------------------

std::string decoderIsaName(DecoderIsa isa) {
  switch (isa) {
    case DecoderIsa::Auto: return "auto";
    case DecoderIsa::Portable: return "portable";
    case DecoderIsa::Avx2: return "avx2+fma";
    case DecoderIsa::Avx512: return "avx512";
  }
  return "unknown";
}

DecoderIsa parseDecoderIsa(const std::string& text) {
  if (text == "auto") return DecoderIsa::Auto;
  if (text == "portable") return DecoderIsa::Portable;
  if (text == "avx2") return DecoderIsa::Avx2;
  if (text == "avx512") return DecoderIsa::Avx512;
  throw Error("unknown instruction set '" + text + "' (expected auto, portable, avx2 or avx512)");
}

// ---- Direction inputs ---------------------------------------------------------------------

namespace {
void addPlaneFeatures(const CompressedBtf& material, const std::array<double, 3>& light,
                      const std::array<double, 3>& view, float* out) {
  if (material.planes.empty()) return;
  float points[6];
  directionPlanePoints(light, view, points);
  sampleDirectionPlanes(material.planes, points, out + directionInputCount(material.directionEncoding));
}
}  // namespace

void addClusterPlaneFeatures(const CompressedBtf& material, int row, const float* points, float* input) {
  const RowPlanes& c = material.clusterPlanes;
  if (c.empty()) return;
  sampleDirectionPlanes(c.resolution, c.features, c.rowValues(row), points,
                        input + directionInputCount(material.directionEncoding) + material.planes.inputCount());
}
void addClusterPlaneFeatures(const CompressedBtf& material, int row, const std::array<double, 3>& light,
                             const std::array<double, 3>& view, float* input) {
  if (material.clusterPlanes.empty()) return;  // before the projections: not on the default's path
  float points[6];
  directionPlanePoints(light, view, points);
  addClusterPlaneFeatures(material, row, points, input);
}

DirectionInput decoderDirectionInput(const CompressedBtf& material, const Direction& light, const Direction& view) {
  DirectionInput d{};
  encodeDirections(material.directionEncoding, light, view, d.data());
  addPlaneFeatures(material, light.unitVector(), view.unitVector(), d.data());
  return d;
}

void decoderDirectionInput(const CompressedBtf& material, const std::array<double, 3>& light,
                           const std::array<double, 3>& view, float* out) {
  encodeDirections(material.directionEncoding, light, view, out);
  addPlaneFeatures(material, light, view, out);
}

std::array<double, 3> unitQueryVector(const std::array<float, 3>& dir, const std::string& what) {
  double x = dir[0], y = dir[1], z = dir[2];
  if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
    throw Error(what + " direction vector is not finite");
  double n = std::sqrt(x * x + y * y + z * z);
  if (!(n > 0)) throw Error(what + " direction vector has zero length");
  x /= n, y /= n, z /= n;
  if (z < 0) {
    std::ostringstream s;
    s << what << " direction (" << dir[0] << ", " << dir[1] << ", " << dir[2]
      << ") points below the horizon (z < 0; z is the surface normal)";
    throw Error(s.str());
  }
  return {x, y, z};
}

DirectionInput NbtfDecoder::directionInput(const Direction& light, const Direction& view) const {
  return decoderDirectionInput(material_, light, view);
}

// ---- Construction -------------------------------------------------------------------------

NbtfDecoder NbtfDecoder::open(const std::string& path, const DecoderOptions& options) {
  return NbtfDecoder(readNbtf(path), options, path);
}

NbtfDecoder::NbtfDecoder(CompressedBtf material, const DecoderOptions& options, const std::string& name)
    : material_(std::move(material)), name_(name) {
  material_.validate(name_);
  build(options);
}

NbtfDecoder::NbtfDecoder(NbtfDecoder&& o) noexcept = default;
NbtfDecoder& NbtfDecoder::operator=(NbtfDecoder&& o) noexcept = default;
NbtfDecoder::~NbtfDecoder() = default;

void NbtfDecoder::build(const DecoderOptions& options) {
  isa_ = options.isa == DecoderIsa::Auto ? detail::bestSupportedIsa() : options.isa;
  if (!decoderIsaSupported(isa_))
    throw Error("instruction set '" + decoderIsaName(isa_) + "' is not supported by this CPU");
  if (material_.isPca()) {
    pca_ = std::make_unique<detail::PcaState>(detail::PcaState{DirectionInterpolator(material_.lights, material_.views)});
    return;
  }
  coefficients_ = dequantizeTexelCoefficients(material_.modulation);  // shapes checked by validate()
  terms_ = material_.modulation.empty() ? 1 : material_.modulation.terms;
  channels_ = material_.modulation.empty() ? 1 : material_.modulation.channels;
  packed_ = std::make_unique<detail::PackedDecoder>(
      detail::packDecoder(material_.decoder, material_.latentDim, directionInputs()));
  packed_->latents = material_.latents.data();
  // The per-row half of the first layer, once, with the same kernel the evaluation uses
  // (so cached and uncached rows give identical results).
  std::size_t bytes = static_cast<std::size_t>(material_.latentRows) * packed_->pad0 * sizeof(float);
  if (bytes <= options.maxCachedFirstLayerBytes) {
    packed_->rowPart.assign(static_cast<std::size_t>(material_.latentRows) * packed_->pad0, 0.0f);
    auto kernel = detail::kernelsFor(isa_).rowPart;
    parallelFor(
        static_cast<std::size_t>(material_.latentRows),
        [&](std::size_t b, std::size_t e) { kernel(*packed_, static_cast<int>(b), static_cast<int>(e), packed_->rowPart.data()); },
        4096);
  }
}

double NbtfDecoder::flopsPerEvaluation() const {
  if (pca_) return 6.0 * material_.latentDim;
  double f = 0;
  for (const DenseLayer& l : material_.decoder.layers) f += 2.0 * l.in * l.out;
  return f;
}

// ---- Checks -------------------------------------------------------------------------------

void NbtfDecoder::checkTexel(int x, int y) const {
  if (x < 0 || y < 0 || x >= width() || y >= height())
    throw Error(describeTexel(x, y) + " is outside the " + std::to_string(width()) + " x " +
                std::to_string(height()) + " material (0 <= x < " + std::to_string(width()) + ", 0 <= y < " +
                std::to_string(height()) + ")");
}

int NbtfDecoder::texelOfUv(float u, float v) const {
  if (!std::isfinite(u) || !std::isfinite(v)) throw Error("texture coordinate (u, v) is not finite");
  auto wrap = [](float t, int n) {
    double i = std::floor(static_cast<double>(t) * n);
    double m = std::fmod(i, static_cast<double>(n));
    if (m < 0) m += n;
    return std::min(static_cast<int>(m), n - 1);
  };
  return wrap(v, height()) * width() + wrap(u, width());
}

// ---- Evaluation core ----------------------------------------------------------------------

namespace {
// Modulated materials: one sample's RGB from its R terms (3R floats) and its texel's R
// coefficients (3R with per-channel coefficients), summed in term order (every path uses this, so they agree bit for bit).
inline void combineTerms(const float* e, const float* f, int terms, int channels, float* rgb) {
  for (int c = 0; c < 3; ++c) {
    const float* ec = channels == 1 ? e : e + c;  // term k's coefficient at k x channels (+ c)
    float v = 0;
    for (int k = 0; k < terms; ++k) v += ec[k * channels] * f[3 * k + c];
    rgb[c] = v;
  }
}
using CombineFn = std::function<void(const float*, const std::int32_t*, int, float*)>;
// n samples' terms -> RGB with their texels' coefficients; empty without modulation.
CombineFn combinerOf(const NbtfDecoder& d) {
  if (!d.modulated()) return {};
  return [&d](const float* terms, const std::int32_t* texels, int n, float* rgb) {
    const int r = d.modulationTerms(), channels = d.modulationChannels();
    for (int i = 0; i < n; ++i)
      combineTerms(d.texelCoefficients().data() + static_cast<std::size_t>(texels[i]) * r * channels,
                   terms + static_cast<std::size_t>(i) * 3 * r, r, channels, rgb + 3 * i);
  };
}
}  // namespace

void NbtfDecoder::evaluateSamples(const std::int32_t* rows, const std::int32_t* texels, const float* dirs,
                                  std::size_t n, float* rgb, OutputScale scale) const {
  // Used for single evaluations: n is small, one thread.
  auto tile = detail::kernelsFor(isa_).tile;
  float* scratch = threadScratch(packed_->scratchFloats());
  float terms[3 * kMaxModulationTerms * detail::kTileRows];
  for (std::size_t begin = 0; begin < n; begin += detail::kTileRows) {
    detail::TileArgs a;
    a.n = static_cast<int>(std::min<std::size_t>(detail::kTileRows, n - begin));
    a.rows = rows + begin;
    a.dirs = dirs + static_cast<std::size_t>(packed_->dirInputs) * begin;
    a.dirStride = packed_->dirInputs;
    a.out = modulated() ? terms : rgb + 3 * begin;
    a.scratch = scratch;
    tile(*packed_, a);
    if (modulated())
      for (int i = 0; i < a.n; ++i)
        combineTerms(coefficients_.data() + static_cast<std::size_t>(texels[begin + i]) * terms_ * channels_,
                     terms + static_cast<std::size_t>(i) * 3 * terms_, terms_, channels_, rgb + 3 * (begin + i));
  }
  if (scale == OutputScale::Linear)
    for (std::size_t i = 0; i < 3 * n; ++i) rgb[i] *= material_.alpha;
}

namespace {
// Runs `count` samples in tiles, in parallel when worth it. fill(begin, n, rows, dirs, texels)
// writes the latent rows, direction inputs and texels of samples [begin, begin + n). With
// `combine` (modulated materials) the tile's terms go to a buffer and combine(terms, texels,
// n, rgb) mixes them per texel.
void runTiles(const detail::PackedDecoder& packed, detail::TileKernel tile, std::size_t count, float* rgb, float alpha,
              OutputScale scale, bool parallel,
              const std::function<void(std::size_t, int, std::int32_t*, float*, std::int32_t*)>& fill,
              const CombineFn& combine) {
  const std::size_t tiles = (count + detail::kTileRows - 1) / detail::kTileRows;
  auto body = [&](std::size_t tileBegin, std::size_t tileEnd) {
    float* scratch = threadScratch(packed.scratchFloats());
    std::int32_t rows[detail::kTileRows], texels[detail::kTileRows];
    float dirs[kMaxDecoderDirectionInputs * detail::kTileRows];
    float terms[3 * kMaxModulationTerms * detail::kTileRows];
    for (std::size_t t = tileBegin; t < tileEnd; ++t) {
      std::size_t begin = t * detail::kTileRows;
      detail::TileArgs a;
      a.n = static_cast<int>(std::min<std::size_t>(detail::kTileRows, count - begin));
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
  if (parallel && count >= kMinParallelSamples) parallelFor(tiles, body, 8);
  else body(0, tiles);
}
}  // namespace

// ---- PCA baseline ------------------------------------------------------------------------

void NbtfDecoder::pcaBasisAt(const std::array<double, 3>& light, const std::array<double, 3>& view,
                             float* meanBasis) const {
  combinePcaRows(material_.pcaMean.data(), material_.pcaBasis.data(), material_.latentDim,
                 pca_->interpolator.weights(light, view), meanBasis, meanBasis + 3);
}

template <class QueryFn>
void NbtfDecoder::evaluatePca(std::size_t count, float* rgb, OutputScale scale, const QueryFn& query) const {
  const int c = material_.latentDim;
  auto body = [&](std::size_t begin, std::size_t end) {
    // Consecutive queries often share their directions: combine the basis once for them.
    std::vector<float> meanBasis(3 + 3 * static_cast<std::size_t>(c));
    std::array<double, 3> lastLight{}, lastView{};
    bool have = false;
    for (std::size_t i = begin; i < end; ++i) {
      int texel = 0;
      std::array<double, 3> l, v;
      query(i, texel, l, v);
      if (!have || l != lastLight || v != lastView) {
        pcaBasisAt(l, v, meanBasis.data());
        lastLight = l, lastView = v, have = true;
      }
      float* out = rgb + 3 * i;
      pcaTexelValue(material_.latents.data() + static_cast<std::size_t>(texel) * c, meanBasis.data(),
                    meanBasis.data() + 3, c, out);
      if (scale == OutputScale::Linear) out[0] *= material_.alpha, out[1] *= material_.alpha, out[2] *= material_.alpha;
    }
  };
  if (count >= kMinParallelSamples) parallelFor(count, body, 1024);
  else body(0, count);
}

// ---- Single evaluations -------------------------------------------------------------------

Rgb NbtfDecoder::evaluate(int x, int y, const Direction& light, const Direction& view, OutputScale scale) const {
  TexelQuery q{x, y, light, view};
  Rgb out;
  evaluate(&q, 1, &out.r, scale);
  return out;
}

Rgb NbtfDecoder::evaluateUv(float u, float v, const Direction& light, const Direction& view, OutputScale scale) const {
  checkHemisphere(light, "light");
  checkHemisphere(view, "view");
  int texel = texelOfUv(u, v);
  if (pca_) return evaluate(texel % width(), texel / width(), light, view, scale);
  std::int32_t row = latentRowOfTexel(texel), texel32 = texel;
  auto dirs = directionInput(light, view);
  if (!material_.clusterPlanes.empty())
    addClusterPlaneFeatures(material_, row, light.unitVector(), view.unitVector(), dirs.data());
  Rgb out;
  evaluateSamples(&row, &texel32, dirs.data(), 1, &out.r, scale);
  return out;
}

Rgb NbtfDecoder::evaluate(const UvQuery& query, OutputScale scale) const {
  Rgb out;
  evaluate(&query, 1, &out.r, scale);
  return out;
}

// ---- Batches ------------------------------------------------------------------------------

void NbtfDecoder::evaluate(const TexelQuery* queries, std::size_t count, float* rgb, OutputScale scale) const {
  // Check everything first: a bad query fails the call before any work.
  for (std::size_t i = 0; i < count; ++i) {
    const TexelQuery& q = queries[i];
    try {
      checkTexel(q.x, q.y);
      checkHemisphere(q.light, "light");
      checkHemisphere(q.view, "view");
    } catch (const Error& e) {
      throw Error(count == 1 ? std::string(e.what()) : "query " + std::to_string(i) + ": " + e.what());
    }
  }
  if (pca_) {
    evaluatePca(count, rgb, scale, [&](std::size_t i, int& texel, std::array<double, 3>& l, std::array<double, 3>& v) {
      const TexelQuery& q = queries[i];
      texel = q.y * width() + q.x;
      l = q.light.unitVector();
      v = q.view.unitVector();
    });
    return;
  }
  runTiles(*packed_, detail::kernelsFor(isa_).tile, count, rgb, material_.alpha, scale, true,
           [&](std::size_t begin, int n, std::int32_t* rows, float* dirs, std::int32_t* texels) {
             // Consecutive queries often share directions: convert each distinct pair once.
             const TexelQuery* last = nullptr;
             DirectionInput d{};
             float points[6];  // the pair's plane points, for cluster planes
             const bool clusterPlanes = !material_.clusterPlanes.empty();
             const int width = packed_->dirInputs;
             for (int i = 0; i < n; ++i) {
               const TexelQuery& q = queries[begin + i];
               texels[i] = q.y * this->width() + q.x;
               rows[i] = latentRowOfTexel(texels[i]);
               if (!last || !(q.light == last->light) || !(q.view == last->view)) {
                 d = directionInput(q.light, q.view), last = &q;
                 if (clusterPlanes) directionPlanePoints(q.light.unitVector(), q.view.unitVector(), points);
               }
               float* slot = dirs + static_cast<std::size_t>(width) * i;
               std::copy_n(d.data(), width, slot);
               if (clusterPlanes) addClusterPlaneFeatures(material_, rows[i], points, slot);
             }
           },
           combinerOf(*this));
}

void NbtfDecoder::evaluate(const UvQuery* queries, std::size_t count, float* rgb, OutputScale scale) const {
  for (std::size_t i = 0; i < count; ++i) {
    try {
      texelOfUv(queries[i].u, queries[i].v);
      unitQueryVector(queries[i].light, "light");
      unitQueryVector(queries[i].view, "view");
    } catch (const Error& e) {
      throw Error(count == 1 ? std::string(e.what()) : "query " + std::to_string(i) + ": " + e.what());
    }
  }
  if (pca_) {
    auto unit = [](const std::array<float, 3>& d) {
      std::array<double, 3> u{d[0], d[1], d[2]};
      double n = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);  // > 0: checked above
      return std::array<double, 3>{u[0] / n, u[1] / n, u[2] / n};
    };
    evaluatePca(count, rgb, scale, [&](std::size_t i, int& texel, std::array<double, 3>& l, std::array<double, 3>& v) {
      const UvQuery& q = queries[i];
      texel = texelOfUv(q.u, q.v);
      l = unit(q.light);
      v = unit(q.view);
    });
    return;
  }
  runTiles(*packed_, detail::kernelsFor(isa_).tile, count, rgb, material_.alpha, scale, true,
           [&](std::size_t begin, int n, std::int32_t* rows, float* dirs, std::int32_t* texels) {
             const int width = packed_->dirInputs;
             for (int i = 0; i < n; ++i) {
               const UvQuery& q = queries[begin + i];
               texels[i] = texelOfUv(q.u, q.v);
               rows[i] = latentRowOfTexel(texels[i]);
               const auto l = unitQueryVector(q.light, "light"), v = unitQueryVector(q.view, "view");
               float* slot = dirs + static_cast<std::size_t>(width) * i;
               decoderDirectionInput(material_, l, v, slot);
               addClusterPlaneFeatures(material_, rows[i], l, v, slot);
             }
           },
           combinerOf(*this));
}

// ---- Images -------------------------------------------------------------------------------

void NbtfDecoder::decodeRows(const Direction& light, const Direction& view, float* rgb, OutputScale scale,
                             bool parallel) const {
  checkHemisphere(light, "light");
  checkHemisphere(view, "view");
  if (pca_) {
    // The basis at this pair once, then 3 dot products of length C per texel.
    const int c = material_.latentDim;
    std::vector<float> meanBasis(3 + 3 * static_cast<std::size_t>(c));
    pcaBasisAt(light.unitVector(), view.unitVector(), meanBasis.data());
    const float factor = material_.alpha;
    auto body = [&](std::size_t begin, std::size_t end) {
      for (std::size_t t = begin; t < end; ++t) {
        float* out = rgb + 3 * t;
        pcaTexelValue(material_.latents.data() + t * c, meanBasis.data(), meanBasis.data() + 3, c, out);
        if (scale == OutputScale::Linear) out[0] *= factor, out[1] *= factor, out[2] *= factor;
      }
    };
    const std::size_t texels = static_cast<std::size_t>(numTexels());
    if (parallel && texels >= kMinParallelSamples) parallelFor(texels, body, 1024);
    else body(0, texels);
    return;
  }
  if (modulated())
    throw Error(name_ + ": decodeRows: a material with per-texel modulation has no per-row values (use decodeImage)");
  decodeRowTerms(light, view, directionInput(light, view), rgb, parallel);
  if (scale == OutputScale::Linear)
    for (std::size_t i = 0, n = 3 * static_cast<std::size_t>(latentRows()); i < n; ++i) rgb[i] *= material_.alpha;
}

void NbtfDecoder::decodeRowTerms(const Direction& light, const Direction& view, float* terms, bool parallel) const {
  if (pca_) throw Error(name_ + ": decodeRowTerms: a PCA file has no decoder terms");
  checkHemisphere(light, "light");
  checkHemisphere(view, "view");
  decodeRowTerms(light, view, directionInput(light, view), terms, parallel);
}

void NbtfDecoder::decodeRowTerms(const Direction& light, const Direction& view, const DirectionInput& dirs, float* out,
                                 bool parallel) const {
  // With cluster planes every row has direction inputs of its own: written per tile.
  const bool perRow = !material_.clusterPlanes.empty();
  float points[6];
  if (perRow) directionPlanePoints(light.unitVector(), view.unitVector(), points);
  const std::size_t count = static_cast<std::size_t>(latentRows());
  const std::size_t outputs = static_cast<std::size_t>(packed_->outputs);
  auto tile = detail::kernelsFor(isa_).tile;
  const std::size_t tiles = (count + detail::kTileRows - 1) / detail::kTileRows;
  auto body = [&](std::size_t tileBegin, std::size_t tileEnd) {
    float* scratch = threadScratch(packed_->scratchFloats());
    std::int32_t rows[detail::kTileRows];
    float rowDirs[kMaxDecoderDirectionInputs * detail::kTileRows];
    const int width = packed_->dirInputs;
    for (std::size_t t = tileBegin; t < tileEnd; ++t) {
      std::size_t begin = t * detail::kTileRows;
      detail::TileArgs a;
      a.n = static_cast<int>(std::min<std::size_t>(detail::kTileRows, count - begin));
      for (int i = 0; i < a.n; ++i) rows[i] = static_cast<std::int32_t>(begin + i);
      a.rows = rows;
      a.dirs = dirs.data();
      a.dirStride = 0;  // one direction for the whole image: its first-layer part once per tile
      if (perRow) {
        for (int i = 0; i < a.n; ++i) {
          float* slot = rowDirs + static_cast<std::size_t>(width) * i;
          std::copy_n(dirs.data(), width, slot);
          addClusterPlaneFeatures(material_, rows[i], points, slot);
        }
        a.dirs = rowDirs;
        a.dirStride = width;
      }
      a.out = out + outputs * begin;
      a.scratch = scratch;
      tile(*packed_, a);
    }
  };
  if (parallel && count >= kMinParallelSamples) parallelFor(tiles, body, 8);
  else body(0, tiles);
}

void NbtfDecoder::imageFromRowTerms(const float* terms, float* rgb, OutputScale scale, int outWidth,
                                    int outHeight) const {
  if (!modulated()) throw Error(name_ + ": imageFromRowTerms: the material has no per-texel modulation");
  if (outWidth == 0) outWidth = width();
  if (outHeight == 0) outHeight = height();
  if (outWidth < 0 || outHeight < 0)
    throw Error("image size " + std::to_string(outWidth) + " x " + std::to_string(outHeight) + " is negative");
  const int r = terms_;
  const float factor = scale == OutputScale::Linear ? material_.alpha : 1.0f;
  for (int y = 0; y < outHeight; ++y) {
    const int sy = y % height();
    float* dst = rgb + static_cast<std::size_t>(y) * outWidth * 3;
    for (int x = 0, sx = 0; x < outWidth; ++x, sx = sx + 1 == width() ? 0 : sx + 1) {
      const int texel = sy * width() + sx;
      combineTerms(coefficients_.data() + static_cast<std::size_t>(texel) * r * channels_,
                   terms + 3 * static_cast<std::size_t>(r) * latentRowOfTexel(texel), r, channels_, dst + 3 * x);
      if (factor != 1.0f) dst[3 * x] *= factor, dst[3 * x + 1] *= factor, dst[3 * x + 2] *= factor;
    }
  }
}

void NbtfDecoder::decodeImage(const Direction& light, const Direction& view, float* rgb, OutputScale scale,
                              int outWidth, int outHeight, bool parallel) const {
  if (outWidth == 0) outWidth = width();
  if (outHeight == 0) outHeight = height();
  if (outWidth < 0 || outHeight < 0)
    throw Error("image size " + std::to_string(outWidth) + " x " + std::to_string(outHeight) + " is negative");
  // Per-texel material at its own size: the rows are the image.
  if (!clustered() && outWidth == width() && outHeight == height()) {
    decodeRows(light, view, rgb, scale, parallel);
    return;
  }
  if (modulated()) {
    // The R terms of every latent row once, then per texel its coefficients' mix.
    checkHemisphere(light, "light");
    checkHemisphere(view, "view");
    std::vector<float> terms(3 * static_cast<std::size_t>(terms_) * latentRows());
    decodeRowTerms(light, view, directionInput(light, view), terms.data(), parallel);
    imageFromRowTerms(terms.data(), rgb, scale, outWidth, outHeight);
    return;
  }
  std::vector<float> rows(3 * static_cast<std::size_t>(latentRows()));
  decodeRows(light, view, rows.data(), scale, parallel);
  for (int y = 0; y < outHeight; ++y) {
    const int sy = y % height();
    float* dst = rgb + static_cast<std::size_t>(y) * outWidth * 3;
    for (int x = 0, sx = 0; x < outWidth; ++x, sx = sx + 1 == width() ? 0 : sx + 1) {
      const float* src = rows.data() + 3 * static_cast<std::size_t>(latentRowOfTexel(sy * width() + sx));
      dst[3 * x + 0] = src[0], dst[3 * x + 1] = src[1], dst[3 * x + 2] = src[2];
    }
  }
}

}  // namespace nbtf
