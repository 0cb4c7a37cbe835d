// Each stored part's own checks: its shape against the material's, finite values, codes in
// range. The part table (nbtf_sections.cpp) names each part's check; a kind runs the checks of
// the parts it may store (checkStoredParts), then its own across parts.
#include "codec/part_checks.h"

#include <cmath>

#include "codec/nbtf_format.h"
#include "codec/texel_modulation.h"
#include "util/error.h"

namespace nbtf::format {
namespace {

// Direction planes, shared or per latent row: `what` names them in messages.
void checkPlanes(const std::string& what, int resolution, int features, const std::vector<float>& values,
                 std::size_t expected, const std::string& name) {
  auto fail = [&](const std::string& message) { return fileError(name, message); };
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
}

// The PCA parts' sizes: C = latentDim components per image channel and per texel.
std::int64_t pcaRows(const CompressedBtf& btf) { return 3 * static_cast<std::int64_t>(btf.numImages()); }

}  // namespace

// Latent + direction inputs (util/directions.h) in, RGB (x terms) out, shapes chained.
void checkDecoderPart(const CompressedBtf& btf, const std::string& name) {
  auto fail = [&](const std::string& message) { return fileError(name, message); };
  if (btf.latentDim < 1 || btf.latentDim > int(kMaxLatentDim)) throw fail("latent dimension " + std::to_string(btf.latentDim) + " is out of range");
  if (btf.decoder.layers.empty()) throw fail("decoder has no layers");
  for (std::size_t i = 0; i < btf.decoder.layers.size(); ++i) {
    const DenseLayer& l = btf.decoder.layers[i];
    std::string which = "decoder layer " + std::to_string(i);
    if (l.in < 1 || l.out < 1 || l.in > int(kMaxLayerWidth) || l.out > int(kMaxLayerWidth))
      throw fail(which + " has shape " + std::to_string(l.out) + " x " + std::to_string(l.in));
    const int directionInputs = btf.directionInputs();
    int expectedIn = i == 0 ? btf.latentDim + directionInputs : btf.decoder.layers[i - 1].out;
    if (l.in != expectedIn)
      throw fail(which + " takes " + std::to_string(l.in) + " inputs, expected " + std::to_string(expectedIn) +
                 (i == 0 ? " (latent + " + std::to_string(directionInputs) + " direction inputs, " +
                              directionEncodingName(btf.directionEncoding) +
                              (btf.planes.empty() ? std::string() : " + direction planes") +
                              (btf.clusterPlanes.empty() ? std::string() : " + cluster planes") + ")"
                        : std::string(" (previous layer's outputs)")));
    if (l.weight.size() != static_cast<std::size_t>(l.in) * l.out || l.bias.size() != static_cast<std::size_t>(l.out))
      throw fail(which + " has " + std::to_string(l.weight.size()) + " weights and " + std::to_string(l.bias.size()) +
                 " biases for shape " + std::to_string(l.out) + " x " + std::to_string(l.in));
    if (l.activation != Activation::None && l.activation != Activation::Relu && l.activation != Activation::Sigmoid)
      throw fail(which + " has unknown activation code " + std::to_string(static_cast<int>(l.activation)));
    if (!allFinite(l.weight) || !allFinite(l.bias)) throw fail(which + " has non-finite parameters (NaN or Inf)");
  }
  const int terms = btf.modulation.empty() ? 1 : btf.modulation.terms;
  if (btf.decoder.layers.back().out != 3 * terms)
    throw fail("decoder outputs " + std::to_string(btf.decoder.layers.back().out) + " values, expected " +
               (terms == 1 ? std::string("3 (RGB)") : std::to_string(3 * terms) + " (RGB x " + std::to_string(terms) +
                                                          " per-texel modulation terms)"));
}

void checkDirectionPlanesPart(const CompressedBtf& btf, const std::string& name) {
  checkPlanes("direction", btf.planes.resolution, btf.planes.features, btf.planes.values, btf.planes.valueCount(), name);
}

void checkClusterPlanesPart(const CompressedBtf& btf, const std::string& name) {
  if (!btf.clusterPlanes.empty() && btf.clusterPlanes.rows != btf.latentRows)
    throw fileError(name, "cluster planes have " + std::to_string(btf.clusterPlanes.rows) +
                              " rows, expected one per latent row (" + std::to_string(btf.latentRows) + ")");
  checkPlanes("cluster", btf.clusterPlanes.resolution, btf.clusterPlanes.features, btf.clusterPlanes.values,
              btf.clusterPlanes.valueCount(), name);
}

void checkLatentsPart(const CompressedBtf& btf, const std::string& name) {
  auto fail = [&](const std::string& message) { return fileError(name, message); };
  if (btf.latentRows < 1) throw fail("no latents");
  if (btf.latents.size() != static_cast<std::size_t>(btf.latentRows) * btf.latentDim)
    throw fail("latents hold " + std::to_string(btf.latents.size()) + " values, expected " + std::to_string(btf.latentRows) +
               " x " + std::to_string(btf.latentDim));
  if (!allFinite(btf.latents)) throw fail("latents contain non-finite values (NaN or Inf)");
}

void checkIdsPart(const CompressedBtf& btf, const std::string& name) {
  auto fail = [&](const std::string& message) { return fileError(name, message); };
  if (btf.ids.size() != static_cast<std::size_t>(btf.numTexels()))
    throw fail("id list has " + std::to_string(btf.ids.size()) + " entries, expected one per texel (" +
               std::to_string(btf.numTexels()) + ")");
  for (std::size_t t = 0; t < btf.ids.size(); ++t)
    if (btf.ids[t] < 0 || btf.ids[t] >= btf.latentRows)
      throw fail("id of texel " + std::to_string(t) + " is " + std::to_string(btf.ids[t]) + ", outside [0, " +
                 std::to_string(btf.latentRows) + ")");
}

// Terms, bits and channels in range, one code per texel and column within its bits, finite
// ranges, orthonormal rotations.
void checkModulationPart(const CompressedBtf& btf, const std::string& name) {
  auto fail = [&](const std::string& message) { return fileError(name, message); };
  const TexelModulation& m = btf.modulation;
  if (m.empty()) return;
  if (m.terms < 1 || m.terms > kMaxModulationTerms)
    throw fail("modulation has " + std::to_string(m.terms) + " terms, expected 1 to " +
               std::to_string(kMaxModulationTerms));
  if (m.bits < 1 || m.bits > 16)
    throw fail("modulation codes have " + std::to_string(m.bits) + " bits, expected 1 to 16");
  if (m.channels != 1 && m.channels != 3)
    throw fail("modulation has " + std::to_string(m.channels) + " channels, expected 1 or 3");
  const int columns = m.columns();
  if (m.codes.size() != static_cast<std::size_t>(btf.numTexels()) * columns)
    throw fail("modulation holds " + std::to_string(m.codes.size()) + " codes, expected " +
               std::to_string(btf.numTexels()) + " texels x " + std::to_string(columns));
  for (int r = 0; r < columns; ++r) {
    const float lo = m.minimum[r], hi = m.maximum[r];
    if (!std::isfinite(lo) || !std::isfinite(hi) || lo > hi || lo < -kMaxModulationMagnitude ||
        hi > kMaxModulationMagnitude)
      throw fail("modulation range of term " + std::to_string(r / m.channels) +
                 (m.channels > 1 ? ", channel " + std::to_string(r % m.channels) : std::string()) +
                 " is invalid (" + std::to_string(lo) + " .. " + std::to_string(hi) + ")");
  }
  if (m.decorrelated) {
    if (m.channels != 3)
      throw fail("decorrelated modulation codes need 3 channels, the file has " + std::to_string(m.channels));
    // Orthonormal to float precision, so that decoding cannot scale a coefficient up.
    for (int r = 0; r < m.terms; ++r) {
      const float* q = &m.rotation[9 * static_cast<std::size_t>(r)];
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
  const std::uint32_t maxCode = (1u << m.bits) - 1;
  for (std::size_t i = 0; i < m.codes.size(); ++i)
    if (m.codes[i] > maxCode)
      throw fail("modulation code " + std::to_string(m.codes[i]) + " of texel " +
                 std::to_string(i / columns) + " exceeds " + std::to_string(m.bits) + " bits");
}

void checkPcaMeanPart(const CompressedBtf& btf, const std::string& name) {
  if (btf.pcaMean.size() != static_cast<std::size_t>(pcaRows(btf)))
    throw fileError(name, "PCA mean holds " + std::to_string(btf.pcaMean.size()) + " values, expected 3 x " +
                              std::to_string(btf.numImages()) + " images");
  if (!allFinite(btf.pcaMean)) throw fileError(name, "PCA mean contains non-finite values (NaN or Inf)");
}

void checkPcaBasisPart(const CompressedBtf& btf, const std::string& name) {
  const std::size_t expected = static_cast<std::size_t>(pcaRows(btf)) * static_cast<std::size_t>(btf.latentDim);
  if (btf.pcaBasis.size() != expected)
    throw fileError(name, "PCA basis holds " + std::to_string(btf.pcaBasis.size()) + " values, expected " +
                              std::to_string(pcaRows(btf)) + " x " + std::to_string(btf.latentDim));
  if (!allFinite(btf.pcaBasis)) throw fileError(name, "PCA basis contains non-finite values (NaN or Inf)");
}

void checkPcaCoefficientsPart(const CompressedBtf& btf, const std::string& name) {
  const int texels = btf.numTexels();
  if (btf.latents.size() != static_cast<std::size_t>(texels) * static_cast<std::size_t>(btf.latentDim))
    throw fileError(name, "PCA coefficients hold " + std::to_string(btf.latents.size()) + " values, expected " +
                              std::to_string(texels) + " x " + std::to_string(btf.latentDim));
  if (!allFinite(btf.latents)) throw fileError(name, "PCA coefficients contain non-finite values (NaN or Inf)");
}

}  // namespace nbtf::format
