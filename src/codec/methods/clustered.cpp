// The clustered neural kind (the paper's method): one latent per cluster, a texel -> cluster
// id list, optionally per-texel modulation of the decoder's terms (codec/texel_modulation.h).
#include <cmath>

#include "codec/methods/neural.h"
#include "codec/nbtf_format.h"
#include "codec/texel_modulation.h"
#include "util/error.h"

namespace nbtf {
namespace {

using format::kMaxModulationMagnitude;
using format::Need;
using format::Part;

void validateIds(const CompressedBtf& btf, const std::string& name) {
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
void validateModulation(const CompressedBtf& btf, const std::string& name) {
  auto fail = [&](const std::string& message) { return fileError(name, message); };
  const TexelModulation& m = btf.modulation;
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

class ClusteredNeural final : public NeuralKind {
 public:
  ClusteredNeural() : NeuralKind(CodecMethod::ClusteredNeural, "clustered-neural", "clustered") {}
  // Every Part listed, no default: the compiler names the kinds a new part must be added to.
  Need need(Part part) const override {
    switch (part) {
      case Part::Info:
      case Part::Directions:
      case Part::Decoder:
      case Part::Latents:
      case Part::Ids: return Need::Required;
      case Part::PcaMean:
      case Part::PcaBasis:
      case Part::PcaCoefficients: return Need::Forbidden;
      case Part::Modulation:
      case Part::Planes:
      case Part::ClusterPlanes:
      case Part::Holdout:
      case Part::Encoder:
      case Part::Metadata: return Need::Optional;
    }
    return Need::Forbidden;
  }
  std::string summary(const CompressedBtf& btf) const override {
    return std::string(name()) + ", k = " + std::to_string(btf.latentRows) + " clusters";
  }
  std::string label(const CompressedBtf& btf) const override {
    const TexelModulation& m = btf.modulation;
    const std::string k = ", k = " + std::to_string(btf.latentRows);
    if (m.empty()) return "clustered neural" + planesLabel(btf) + k;
    return "clustered neural + per-texel modulation (" + std::to_string(m.terms) + " term" + (m.terms > 1 ? "s" : "") +
           (m.channels > 1 ? ", per channel" : "") + ")" + planesLabel(btf) + k;
  }
  int sweepParameter(const CompressedBtf& btf) const override { return btf.latentRows; }
  void validate(const CompressedBtf& btf, const std::string& name) const override {
    validateNeuralParts(btf, name);
    validateIds(btf, name);
    if (!btf.modulation.empty()) validateModulation(btf, name);
  }
};

}  // namespace

const MethodKind& clusteredNeuralMethod() {
  static const ClusteredNeural kind;
  return kind;
}

}  // namespace nbtf
