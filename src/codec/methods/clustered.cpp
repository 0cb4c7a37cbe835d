// The clustered neural kind (the paper's method): one latent per cluster, a texel -> cluster
// id list, optionally per-texel modulation of the decoder's terms (codec/texel_modulation.h).
#include "codec/methods/neural.h"
#include "codec/texel_modulation.h"

namespace nbtf {
namespace {

using format::Need;
using format::Part;

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
  }
};

}  // namespace

const MethodKind& clusteredNeuralMethod() {
  static const ClusteredNeural kind;
  return kind;
}

}  // namespace nbtf
