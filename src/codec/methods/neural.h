// What the two neural kinds (clustered.cpp, per_texel.cpp) share: a decoder MLP over a latent
// and the direction inputs, latent rows, direction planes, and how they are stored.
#pragma once
#include <memory>
#include <string>

#include "codec/methods/evaluator.h"
#include "codec/methods/method.h"

namespace nbtf {

// The checks of every part the kind may store (checkStoredParts: decoder, planes, latents, and
// the clustered kind's ids and modulation), then that no PCA part is held and that the values
// in memory are the ones their storage holds (roundToStorage).
void validateNeuralParts(const CompressedBtf& btf, const std::string& name);

// " + direction planes (9 x 9 x 2) + cluster planes (...)", or "" without planes.
std::string planesLabel(const CompressedBtf& btf);

// The base of the two neural kinds: what they show and how they evaluate is the same.
class NeuralKind : public MethodKind {
 public:
  using MethodKind::MethodKind;
  // `nbtf info`'s lines for the neural parts: direction inputs, planes, alpha, decoder,
  // latents, modulation, storage.
  std::vector<std::pair<std::string, std::string>> infoFields(const CompressedBtf& btf) const override;
  // The decoder MLP's evaluator (neural_evaluator.cpp): packed once, evaluated in SIMD tiles.
  std::unique_ptr<detail::MaterialEvaluator> evaluator(const CompressedBtf& btf, DecoderIsa isa,
                                                       const DecoderOptions& options) const override;
};

}  // namespace nbtf
