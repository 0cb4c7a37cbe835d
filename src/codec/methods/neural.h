// What the two neural kinds (clustered.cpp, per_texel.cpp) share: a decoder MLP over a latent
// and the direction inputs, latent rows, direction planes, and how they are stored.
#pragma once
#include <memory>
#include <string>

#include "codec/methods/evaluator.h"
#include "codec/methods/method.h"

namespace nbtf {

// The decoder, the direction and cluster planes, the latents, and that the values in memory
// are the ones their storage holds (roundToStorage). The kind checks its ids and modulation.
void validateNeuralParts(const CompressedBtf& btf, const std::string& name);

// " + direction planes (9 x 9 x 2) + cluster planes (...)", or "" without planes.
std::string planesLabel(const CompressedBtf& btf);

// The decoder MLP's evaluator (neural_evaluator.cpp): packed once, evaluated in SIMD tiles.
std::unique_ptr<detail::MaterialEvaluator> makeNeuralEvaluator(const CompressedBtf& btf, DecoderIsa isa,
                                                               const DecoderOptions& options);

}  // namespace nbtf
