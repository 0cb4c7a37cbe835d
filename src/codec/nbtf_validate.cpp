// CompressedBtf::validate: every invariant of a material that the writer and the reader check.
#include <algorithm>
#include <climits>
#include <cmath>
#include <nlohmann/json.hpp>

#include "codec/nbtf_format.h"
#include "util/error.h"
#include "util/half.h"

namespace nbtf {
namespace {

using format::int8Code;
using format::int8RowScale;
using format::kMaxJsonDepth;
using format::kMaxLatentDim;
using format::kMaxLayerWidth;
using format::kMaxModulationMagnitude;
using format::kMaxPcaComponents;
using format::kMaxSide;
using format::storagePlanesHalf;

bool allFinite(const std::vector<float>& v) {
  return std::all_of(v.begin(), v.end(), [](float x) { return std::isfinite(x); });
}

// Nesting depth of a JSON text (brackets outside strings); bounds the parser's work on
// hostile metadata before nlohmann sees it.
int jsonDepth(const std::string& text) {
  int depth = 0, maxDepth = 0;
  bool inString = false, escape = false;
  for (char c : text) {
    if (inString) {
      if (escape) escape = false;
      else if (c == '\\') escape = true;
      else if (c == '"') inString = false;
    } else if (c == '"') {
      inString = true;
    } else if (c == '{' || c == '[') {
      maxDepth = std::max(maxDepth, ++depth);
    } else if (c == '}' || c == ']') {
      --depth;
    }
  }
  return maxDepth;
}

void checkMetadata(const std::string& json, const std::string& name) {
  if (jsonDepth(json) > kMaxJsonDepth)
    throw fileError(name, "metadata JSON is nested deeper than " + std::to_string(kMaxJsonDepth) + " levels");
  auto first = json.find_first_not_of(" \t\r\n");
  if (first == std::string::npos || json[first] != '{' || !nlohmann::json::accept(json))
    throw fileError(name, "metadata is not a valid JSON object");
}

}  // namespace

void CompressedBtf::validate(const std::string& name) const {
  auto fail = [&](const std::string& m) { return fileError(name, m); };
  if (method != CodecMethod::ClusteredNeural && method != CodecMethod::PerTexelNeural && method != CodecMethod::Pca)
    throw fail("unknown method code " + std::to_string(static_cast<int>(method)));
  if (!isDirectionEncoding(static_cast<int>(directionEncoding)))
    throw fail("unknown direction encoding code " + std::to_string(static_cast<int>(directionEncoding)));
  if (valueSpace != ValueSpace::LinearOverAlpha)
    throw fail("unknown value space code " + std::to_string(static_cast<int>(valueSpace)));

  // Geometry
  if (width < 1 || height < 1 || width > int(kMaxSide) || height > int(kMaxSide))
    throw fail("texel size " + std::to_string(width) + " x " + std::to_string(height) + " is out of range");
  if (static_cast<std::int64_t>(width) * height > INT_MAX) throw fail("too many texels");
  if (sourceWidth < 1 || sourceHeight < 1 || sourceWidth > int(kMaxSide) || sourceHeight > int(kMaxSide))
    throw fail("source image size " + std::to_string(sourceWidth) + " x " + std::to_string(sourceHeight) +
               " is out of range");
  if (crop.empty()) {
    if (width != sourceWidth || height != sourceHeight)
      throw fail("texel size differs from the source image size but no crop is recorded");
  } else {
    if (crop.x < 0 || crop.y < 0 || crop.width < 1 || crop.height < 1 ||
        static_cast<std::int64_t>(crop.x) + crop.width > sourceWidth ||
        static_cast<std::int64_t>(crop.y) + crop.height > sourceHeight)
      throw fail("crop " + std::to_string(crop.x) + "," + std::to_string(crop.y) + "," + std::to_string(crop.width) +
                 "," + std::to_string(crop.height) + " lies outside the " + std::to_string(sourceWidth) + " x " +
                 std::to_string(sourceHeight) + " source images");
    if (crop.width != width || crop.height != height) throw fail("crop size differs from the texel size");
  }
  if (lights.empty() || views.empty()) throw fail("no light or view directions");
  if (static_cast<std::int64_t>(lights.size()) * static_cast<std::int64_t>(views.size()) > INT_MAX)
    throw fail("too many images");
  for (std::size_t i = 0; i < lights.size(); ++i) {
    try {
      checkHemisphere(lights[i], "light " + std::to_string(i));
    } catch (const Error& e) {
      throw fail(e.what());
    }
  }
  for (std::size_t i = 0; i < views.size(); ++i) {
    try {
      checkHemisphere(views[i], "view " + std::to_string(i));
    } catch (const Error& e) {
      throw fail(e.what());
    }
  }
  if (!std::isfinite(alpha) || !(alpha > 0)) throw fail("alpha must be a finite positive number");

  if (isPca()) validatePca(name);
  else validateNeural(name);

  // Provenance
  for (std::size_t i = 0; i < holdoutImages.size(); ++i) {
    int h = holdoutImages[i];
    if (h < 0 || h >= numImages())
      throw fail("hold-out image index " + std::to_string(h) + " is outside [0, " + std::to_string(numImages()) + ")");
    if (i && h <= holdoutImages[i - 1]) throw fail("hold-out image indices are not strictly ascending");
  }
  checkMetadata(metadataJson, name);
}

void CompressedBtf::validatePca(const std::string& name) const {
  auto fail = [&](const std::string& m) { return fileError(name, m); };
  const std::int64_t rows = 3 * static_cast<std::int64_t>(numImages());
  const int texels = numTexels();
  if (!decoder.layers.empty() || !ids.empty()) throw fail("PCA file has a decoder or an id list");
  if (!planes.values.empty() || !clusterPlanes.values.empty()) throw fail("PCA file has direction or cluster planes");
  const std::int64_t maxComponents = std::min<std::int64_t>({rows, texels, kMaxPcaComponents});
  if (latentDim < 1 || latentDim > maxComponents)
    throw fail(std::to_string(latentDim) + " PCA components, expected 1 to " + std::to_string(maxComponents) +
               " (at most min(texels, 3 x images))");
  if (latentRows != texels)
    throw fail("PCA file has " + std::to_string(latentRows) + " coefficient rows for " + std::to_string(texels) +
               " texels");
  const std::size_t c = static_cast<std::size_t>(latentDim);
  if (pcaMean.size() != static_cast<std::size_t>(rows))
    throw fail("PCA mean holds " + std::to_string(pcaMean.size()) + " values, expected 3 x " +
               std::to_string(numImages()) + " images");
  if (pcaBasis.size() != static_cast<std::size_t>(rows) * c)
    throw fail("PCA basis holds " + std::to_string(pcaBasis.size()) + " values, expected " + std::to_string(rows) +
               " x " + std::to_string(c));
  if (latents.size() != static_cast<std::size_t>(texels) * c)
    throw fail("PCA coefficients hold " + std::to_string(latents.size()) + " values, expected " +
               std::to_string(texels) + " x " + std::to_string(c));
  if (!allFinite(pcaMean)) throw fail("PCA mean contains non-finite values (NaN or Inf)");
  if (!allFinite(pcaBasis)) throw fail("PCA basis contains non-finite values (NaN or Inf)");
  if (!allFinite(latents)) throw fail("PCA coefficients contain non-finite values (NaN or Inf)");
}

void CompressedBtf::validateNeural(const std::string& name) const {
  auto fail = [&](const std::string& m) { return fileError(name, m); };
  // Decoder: latent + direction inputs (util/directions.h) in, RGB out, shapes chained.
  if (latentDim < 1 || latentDim > int(kMaxLatentDim)) throw fail("latent dimension " + std::to_string(latentDim) + " is out of range");
  if (decoder.layers.empty()) throw fail("decoder has no layers");
  for (std::size_t i = 0; i < decoder.layers.size(); ++i) {
    const DenseLayer& l = decoder.layers[i];
    std::string which = "decoder layer " + std::to_string(i);
    if (l.in < 1 || l.out < 1 || l.in > int(kMaxLayerWidth) || l.out > int(kMaxLayerWidth))
      throw fail(which + " has shape " + std::to_string(l.out) + " x " + std::to_string(l.in));
    const int directionInputs = this->directionInputs();
    int expectedIn = i == 0 ? latentDim + directionInputs : decoder.layers[i - 1].out;
    if (l.in != expectedIn)
      throw fail(which + " takes " + std::to_string(l.in) + " inputs, expected " + std::to_string(expectedIn) +
                 (i == 0 ? " (latent + " + std::to_string(directionInputs) + " direction inputs, " +
                              directionEncodingName(directionEncoding) +
                              (planes.empty() ? std::string() : " + direction planes") +
                              (clusterPlanes.empty() ? std::string() : " + cluster planes") + ")"
                        : std::string(" (previous layer's outputs)")));
    if (l.weight.size() != static_cast<std::size_t>(l.in) * l.out || l.bias.size() != static_cast<std::size_t>(l.out))
      throw fail(which + " has " + std::to_string(l.weight.size()) + " weights and " + std::to_string(l.bias.size()) +
                 " biases for shape " + std::to_string(l.out) + " x " + std::to_string(l.in));
    if (l.activation != Activation::None && l.activation != Activation::Relu && l.activation != Activation::Sigmoid)
      throw fail(which + " has unknown activation code " + std::to_string(static_cast<int>(l.activation)));
    if (!allFinite(l.weight) || !allFinite(l.bias)) throw fail(which + " has non-finite parameters (NaN or Inf)");
  }
  const int terms = modulation.empty() ? 1 : modulation.terms;
  if (decoder.layers.back().out != 3 * terms)
    throw fail("decoder outputs " + std::to_string(decoder.layers.back().out) + " values, expected " +
               (terms == 1 ? std::string("3 (RGB)") : std::to_string(3 * terms) + " (RGB x " + std::to_string(terms) +
                                                          " per-texel modulation terms)"));

  // Direction planes, shared and per latent row: `what` names them in messages.
  auto checkPlanes = [&](const std::string& what, int resolution, int features, const std::vector<float>& values,
                         std::size_t expected) {
    if (features == 0) {
      if (!values.empty()) throw fail(what + " plane values without features");
      return;
    }
    if (features < 0 || features > DirectionPlanes::kMaxFeatures || resolution < 2 ||
        resolution > DirectionPlanes::kMaxResolution)
      throw fail(what + " planes of " + std::to_string(resolution) + " x " + std::to_string(resolution) +
                 " points x " + std::to_string(features) + " features are out of range (2.." +
                 std::to_string(DirectionPlanes::kMaxResolution) + " points, 1.." +
                 std::to_string(DirectionPlanes::kMaxFeatures) + " features)");
    if (values.size() != expected)
      throw fail(what + " planes hold " + std::to_string(values.size()) + " values, expected " +
                 std::to_string(expected));
    if (!allFinite(values)) throw fail(what + " planes contain non-finite values (NaN or Inf)");
  };
  checkPlanes("direction", planes.resolution, planes.features, planes.values, planes.valueCount());
  if (!clusterPlanes.empty() && clusterPlanes.rows != latentRows)
    throw fail("cluster planes have " + std::to_string(clusterPlanes.rows) + " rows, expected one per latent row (" +
               std::to_string(latentRows) + ")");
  checkPlanes("cluster", clusterPlanes.resolution, clusterPlanes.features, clusterPlanes.values,
              clusterPlanes.valueCount());

  // Latents and ids
  if (latentRows < 1) throw fail("no latents");
  if (latents.size() != static_cast<std::size_t>(latentRows) * latentDim)
    throw fail("latents hold " + std::to_string(latents.size()) + " values, expected " + std::to_string(latentRows) +
               " x " + std::to_string(latentDim));
  if (!allFinite(latents)) throw fail("latents contain non-finite values (NaN or Inf)");
  int texels = numTexels();
  if (method == CodecMethod::ClusteredNeural) {
    if (ids.size() != static_cast<std::size_t>(texels))
      throw fail("id list has " + std::to_string(ids.size()) + " entries, expected one per texel (" +
                 std::to_string(texels) + ")");
    for (std::size_t t = 0; t < ids.size(); ++t)
      if (ids[t] < 0 || ids[t] >= latentRows)
        throw fail("id of texel " + std::to_string(t) + " is " + std::to_string(ids[t]) + ", outside [0, " +
                   std::to_string(latentRows) + ")");
  } else {
    if (!ids.empty()) throw fail("per-texel file has an id list");
    if (latentRows != texels)
      throw fail("per-texel file has " + std::to_string(latentRows) + " latents for " + std::to_string(texels) +
                 " texels");
  }
  if (!pcaMean.empty() || !pcaBasis.empty()) throw fail(codecMethodName(method) + " file has a PCA mean or basis");

  // Half-precision storage holds exactly the values in memory (roundToStorage).
  auto halfExact = [](const std::vector<float>& v) {
    return std::all_of(v.begin(), v.end(), [](float x) { return roundToHalf(x) == x; });
  };
  if (storage.decoderInt8 && storage.decoderHalf) throw fail("decoder storage is both half and 8-bit");
  if (storage.decoderInt8)
    for (const DenseLayer& l : decoder.layers) {
      bool exact = halfExact(l.bias);
      for (int o = 0; o < l.out && exact; ++o) {
        const float* row = l.weight.data() + static_cast<std::size_t>(o) * l.in;
        const float scale = int8RowScale(row, l.in);
        for (int i = 0; i < l.in && exact; ++i) exact = static_cast<float>(int8Code(row[i], scale)) * scale == row[i];
      }
      if (!exact)
        throw fail("decoder is to be stored with 8-bit weights and half biases but holds values they cannot "
                   "represent (round them with roundToStorage first)");
    }
  if (storage.decoderHalf)
    for (const DenseLayer& l : decoder.layers)
      if (!halfExact(l.weight) || !halfExact(l.bias))
        throw fail("decoder is to be stored in half precision but holds values that half cannot represent "
                   "(round them with roundToStorage first)");
  if (storagePlanesHalf(*this) && !halfExact(planes.values))
    throw fail("direction planes are to be stored in half precision but hold values that half cannot represent");
  const int clusterPlaneBytes = format::clusterPlaneBytesPerValue(*this);
  if (clusterPlaneBytes == 1 && !format::clusterPlanes8BitExact(clusterPlanes))
    throw fail("cluster planes are to be stored in 8 bits but hold values that their codes cannot represent");
  if (clusterPlaneBytes == 2 && !halfExact(clusterPlanes.values))
    throw fail("cluster planes are to be stored in half precision but hold values that half cannot represent");
  if (storage.latentsHalf && !halfExact(latents))
    throw fail("latents are to be stored in half precision but hold values that half cannot represent");

  // Per-texel modulation
  if (modulation.empty()) {
    if (!modulation.codes.empty()) throw fail("modulation codes without modulation terms");
    return;
  }
  if (method != CodecMethod::ClusteredNeural) throw fail("per-texel modulation is only defined for the clustered method");
  if (modulation.terms < 1 || modulation.terms > kMaxModulationTerms)
    throw fail("modulation has " + std::to_string(modulation.terms) + " terms, expected 1 to " +
               std::to_string(kMaxModulationTerms));
  if (modulation.bits < 1 || modulation.bits > 16)
    throw fail("modulation codes have " + std::to_string(modulation.bits) + " bits, expected 1 to 16");
  if (modulation.channels != 1 && modulation.channels != 3)
    throw fail("modulation has " + std::to_string(modulation.channels) + " channels, expected 1 or 3");
  const int columns = modulation.columns();
  if (modulation.codes.size() != static_cast<std::size_t>(texels) * columns)
    throw fail("modulation holds " + std::to_string(modulation.codes.size()) + " codes, expected " +
               std::to_string(texels) + " texels x " + std::to_string(columns));
  for (int r = 0; r < columns; ++r) {
    const float lo = modulation.minimum[r], hi = modulation.maximum[r];
    if (!std::isfinite(lo) || !std::isfinite(hi) || lo > hi || lo < -kMaxModulationMagnitude ||
        hi > kMaxModulationMagnitude)
      throw fail("modulation range of term " + std::to_string(r / modulation.channels) +
                 (modulation.channels > 1 ? ", channel " + std::to_string(r % modulation.channels) : std::string()) +
                 " is invalid (" + std::to_string(lo) + " .. " + std::to_string(hi) + ")");
  }
  if (modulation.decorrelated) {
    if (modulation.channels != 3)
      throw fail("decorrelated modulation codes need 3 channels, the file has " + std::to_string(modulation.channels));
    // Orthonormal to float precision, so that decoding cannot scale a coefficient up.
    for (int r = 0; r < modulation.terms; ++r) {
      const float* q = &modulation.rotation[9 * static_cast<std::size_t>(r)];
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          double dot = 0;
          for (int c = 0; c < 3; ++c) dot += static_cast<double>(q[3 * c + i]) * q[3 * c + j];
          if (!(std::fabs(dot - (i == j ? 1.0 : 0.0)) <= 1e-5))
            throw fail("the modulation rotation of term " + std::to_string(r) + " is not orthonormal (axes " +
                       std::to_string(i) + " and " + std::to_string(j) + ": dot product " + std::to_string(dot) + ")");
        }
    }
  }
  const std::uint32_t maxCode = (1u << modulation.bits) - 1;
  for (std::size_t i = 0; i < modulation.codes.size(); ++i)
    if (modulation.codes[i] > maxCode)
      throw fail("modulation code " + std::to_string(modulation.codes[i]) + " of texel " +
                 std::to_string(i / columns) + " exceeds " + std::to_string(modulation.bits) + " bits");
}

}  // namespace nbtf
