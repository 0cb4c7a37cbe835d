// The parts both neural kinds store, and their checks.
#include "codec/methods/neural.h"

#include <cstdio>

#include "codec/nbtf_format.h"
#include "codec/texel_modulation.h"
#include "util/error.h"
#include "util/half.h"
#include "util/printable.h"

namespace nbtf {
namespace {

using format::allFinite;
using format::int8Code;
using format::int8RowScale;
using format::kMaxLatentDim;
using format::kMaxLayerWidth;
using format::storagePlanesHalf;

// Latent + direction inputs (util/directions.h) in, RGB (x terms) out, shapes chained.
void checkDecoder(const CompressedBtf& btf, const std::string& name) {
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

// Stored in half or 8 bits, the values in memory are exactly the stored ones (roundToStorage).
void checkStorageExact(const CompressedBtf& btf, const std::string& name) {
  auto fail = [&](const std::string& message) { return fileError(name, message); };
  auto halfExact = [](const std::vector<float>& v) {
    return std::all_of(v.begin(), v.end(), [](float x) { return roundToHalf(x) == x; });
  };
  if (btf.storage.decoderInt8 && btf.storage.decoderHalf) throw fail("decoder storage is both half and 8-bit");
  if (btf.storage.decoderInt8)
    for (const DenseLayer& l : btf.decoder.layers) {
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
  if (btf.storage.decoderHalf)
    for (const DenseLayer& l : btf.decoder.layers)
      if (!halfExact(l.weight) || !halfExact(l.bias))
        throw fail("decoder is to be stored in half precision but holds values that half cannot represent "
                   "(round them with roundToStorage first)");
  if (storagePlanesHalf(btf) && !halfExact(btf.planes.values))
    throw fail("direction planes are to be stored in half precision but hold values that half cannot represent");
  const int clusterPlaneBytes = format::clusterPlaneBytesPerValue(btf);
  if (clusterPlaneBytes == 1 && !format::clusterPlanes8BitExact(btf.clusterPlanes))
    throw fail("cluster planes are to be stored in 8 bits but hold values that their codes cannot represent");
  if (clusterPlaneBytes == 2 && !halfExact(btf.clusterPlanes.values))
    throw fail("cluster planes are to be stored in half precision but hold values that half cannot represent");
  if (btf.storage.latentsHalf && !halfExact(btf.latents))
    throw fail("latents are to be stored in half precision but hold values that half cannot represent");
}

std::string activationName(Activation a) {
  switch (a) {
    case Activation::Relu: return "ReLU";
    case Activation::Sigmoid: return "sigmoid";
    default: return "linear";
  }
}

// "12 -> 106 (ReLU) -> 106 (ReLU) -> 3 (linear), 24,383 parameters"
std::string decoderDescription(const Mlp& mlp) {
  std::string s = mlp.layers.empty() ? "none" : std::to_string(mlp.layers.front().in);
  for (const auto& l : mlp.layers) s += " -> " + std::to_string(l.out) + " (" + activationName(l.activation) + ")";
  std::size_t params = 0;
  for (const auto& l : mlp.layers) params += l.parameterCount();
  return s + ", " + groupedDigits(params) + " parameters";
}

// "each latent row's own planes over light, view and half vector, 8 x 8 points x 4 features
// each (+12 decoder inputs)"
std::string planesDescription(const char* whose, int resolution, int features, int inputs) {
  return std::string(whose) + " over light, view and half vector, " + std::to_string(resolution) + " x " +
         std::to_string(resolution) + " points x " + std::to_string(features) + " features each (+" +
         std::to_string(inputs) + " decoder inputs)";
}

}  // namespace

std::vector<std::pair<std::string, std::string>> NeuralKind::infoFields(const CompressedBtf& btf) const {
  std::vector<std::pair<std::string, std::string>> fields;
  fields.push_back({"directions", directionEncodingDescription(btf.directionEncoding)});
  const DirectionPlanes& p = btf.planes;
  const RowPlanes& c = btf.clusterPlanes;
  if (!p.empty())
    fields.push_back({"planes", planesDescription("direction planes", p.resolution, p.features, p.inputCount())});
  if (!c.empty())
    fields.push_back(
        {"cluster planes", planesDescription("each latent row's own planes", c.resolution, c.features, c.inputCount())});
  char alpha[64];
  std::snprintf(alpha, sizeof alpha, "%.6g", btf.alpha);
  fields.push_back({"alpha", std::string(alpha) + " (decoder output x alpha = linear RGB)"});
  fields.push_back({"decoder", decoderDescription(btf.decoder)});
  fields.push_back({"latents", std::to_string(btf.latentRows) + " x " + std::to_string(btf.latentDim)});
  if (!btf.modulation.empty())
    fields.push_back({"modulation", modulationDescription(btf.modulation) + ", refit to the trained terms"});
  fields.push_back({"storage", storageDescription(btf)});
  return fields;
}

void validateNeuralParts(const CompressedBtf& btf, const std::string& name) {
  auto fail = [&](const std::string& message) { return fileError(name, message); };
  checkDecoder(btf, name);
  checkPlanes("direction", btf.planes.resolution, btf.planes.features, btf.planes.values, btf.planes.valueCount(), name);
  if (!btf.clusterPlanes.empty() && btf.clusterPlanes.rows != btf.latentRows)
    throw fail("cluster planes have " + std::to_string(btf.clusterPlanes.rows) + " rows, expected one per latent row (" +
               std::to_string(btf.latentRows) + ")");
  checkPlanes("cluster", btf.clusterPlanes.resolution, btf.clusterPlanes.features, btf.clusterPlanes.values,
              btf.clusterPlanes.valueCount(), name);
  if (btf.latentRows < 1) throw fail("no latents");
  if (btf.latents.size() != static_cast<std::size_t>(btf.latentRows) * btf.latentDim)
    throw fail("latents hold " + std::to_string(btf.latents.size()) + " values, expected " + std::to_string(btf.latentRows) +
               " x " + std::to_string(btf.latentDim));
  if (!allFinite(btf.latents)) throw fail("latents contain non-finite values (NaN or Inf)");
  if (!btf.pcaMean.empty() || !btf.pcaBasis.empty())
    throw fail(methodKind(btf.method).name() + std::string(" file has a PCA mean or basis"));
  checkStorageExact(btf, name);
  if (btf.modulation.empty() && !btf.modulation.codes.empty()) throw fail("modulation codes without modulation terms");
}

std::string planesLabel(const CompressedBtf& btf) {
  std::string planes;
  if (!btf.planes.empty())
    planes += " + direction planes (" + std::to_string(btf.planes.resolution) + " x " +
              std::to_string(btf.planes.resolution) + " x " + std::to_string(btf.planes.features) + ")";
  if (!btf.clusterPlanes.empty())
    planes += " + cluster planes (" + std::to_string(btf.clusterPlanes.resolution) + " x " +
              std::to_string(btf.clusterPlanes.resolution) + " x " + std::to_string(btf.clusterPlanes.features) + ")";
  return planes;
}

}  // namespace nbtf
