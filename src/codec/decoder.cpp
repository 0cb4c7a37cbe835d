#include "codec/decoder.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <sstream>

#include "codec/decoder_kernels.h"
#include "codec/methods/evaluator.h"
#include "codec/methods/method.h"
#include "codec/texel_modulation.h"
#include "util/error.h"
#include "util/parallel.h"

namespace nbtf {
namespace {

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
  coefficients_ = dequantizeTexelCoefficients(material_.modulation);  // shapes checked by validate()
  terms_ = material_.modulation.empty() ? 1 : material_.modulation.terms;
  channels_ = material_.modulation.empty() ? 1 : material_.modulation.channels;
  evaluator_ = methodKind(material_.method, name_).evaluator(material_, isa_, options);
}

double NbtfDecoder::flopsPerEvaluation() const { return evaluator_->flopsPerEvaluation(); }

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

// ---- Single evaluations -------------------------------------------------------------------

Rgb NbtfDecoder::evaluate(int x, int y, const Direction& light, const Direction& view, OutputScale scale) const {
  TexelQuery q{x, y, light, view};
  Rgb out;
  evaluate(&q, 1, &out.r, scale);
  return out;
}

Rgb NbtfDecoder::evaluateUv(float u, float v, const Direction& light, const Direction& view, OutputScale scale) const {
  const int texel = texelOfUv(u, v);
  return evaluate(texel % width(), texel / width(), light, view, scale);
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
  evaluator_->evaluate(*this, queries, count, rgb, scale);
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
  evaluator_->evaluate(*this, queries, count, rgb, scale);
}

// ---- Images -------------------------------------------------------------------------------

void NbtfDecoder::decodeRows(const Direction& light, const Direction& view, float* rgb, OutputScale scale,
                             bool parallel) const {
  checkHemisphere(light, "light");
  checkHemisphere(view, "view");
  if (modulated())
    throw Error(name_ + ": decodeRows: a material with per-texel modulation has no per-row values (use decodeImage)");
  evaluator_->decodeRows(*this, light, view, rgb, scale, parallel);
}

void NbtfDecoder::decodeRowTerms(const Direction& light, const Direction& view, float* terms, bool parallel) const {
  checkHemisphere(light, "light");
  checkHemisphere(view, "view");
  evaluator_->decodeRowTerms(*this, light, view, terms, parallel);
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
      detail::combineTerms(coefficients_.data() + static_cast<std::size_t>(texel) * r * channels_,
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
    evaluator_->decodeRowTerms(*this, light, view, terms.data(), parallel);
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
