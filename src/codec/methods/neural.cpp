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

using format::int8Code;
using format::int8RowScale;
using format::storagePlanesHalf;

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
  const MethodKind& kind = methodKind(btf.method);
  checkStoredParts(btf, kind, name);
  if (!btf.pcaMean.empty() || !btf.pcaBasis.empty()) throw fail(kind.name() + std::string(" file has a PCA mean or basis"));
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
