// The per-texel neural kind (the earlier neural BTF, our baseline): one latent per texel, no
// id list, no modulation.
#include "codec/methods/neural.h"
#include "util/error.h"

namespace nbtf {
namespace {

using format::Need;
using format::Part;

class PerTexelNeural final : public NeuralKind {
 public:
  PerTexelNeural() : NeuralKind(CodecMethod::PerTexelNeural, "per-texel-neural", "per-texel") {}
  // Every Part listed, no default: the compiler names the kinds a new part must be added to.
  Need need(Part part) const override {
    switch (part) {
      case Part::Info:
      case Part::Directions:
      case Part::Decoder:
      case Part::Latents: return Need::Required;
      case Part::PcaMean:
      case Part::PcaBasis:
      case Part::PcaCoefficients:
      case Part::Ids:
      case Part::Modulation: return Need::Forbidden;
      case Part::Planes:
      case Part::ClusterPlanes:
      case Part::Holdout:
      case Part::Encoder:
      case Part::Metadata: return Need::Optional;
    }
    return Need::Forbidden;
  }
  std::string summary(const CompressedBtf&) const override { return std::string(name()) + ", one latent per texel"; }
  std::string label(const CompressedBtf& btf) const override { return "per-texel neural" + planesLabel(btf); }
  int sweepParameter(const CompressedBtf&) const override { return 0; }
  void validate(const CompressedBtf& btf, const std::string& name) const override {
    auto fail = [&](const std::string& message) { return fileError(name, message); };
    validateNeuralParts(btf, name);
    if (!btf.ids.empty()) throw fail("per-texel file has an id list");
    if (btf.latentRows != btf.numTexels())
      throw fail("per-texel file has " + std::to_string(btf.latentRows) + " latents for " +
                 std::to_string(btf.numTexels()) + " texels");
    if (!btf.modulation.empty()) throw fail("per-texel modulation is only defined for the clustered method");
  }
};

}  // namespace

const MethodKind& perTexelNeuralMethod() {
  static const PerTexelNeural kind;
  return kind;
}

}  // namespace nbtf
