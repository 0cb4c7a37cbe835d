// Internal to the decoder: what a model kind evaluates once NbtfDecoder has checked a call's
// arguments (texels in range, directions on the hemisphere, sizes). One implementation per
// representation: the neural decoder MLP (neural_evaluator.cpp, for the clustered and the
// per-texel kinds) and PCA's mean and basis (pca.cpp). The decoder keeps the checks, the
// texel -> row mapping and the image assembly; the evaluator the hot loops. Not a public header.
#pragma once
#include <cstddef>

#include "codec/decoder.h"

namespace nbtf::detail {

class MaterialEvaluator {
 public:
  virtual ~MaterialEvaluator() = default;
  // FLOPs of one evaluation, as NbtfDecoder::flopsPerEvaluation describes.
  virtual double flopsPerEvaluation() const = 0;
  // Checked batches: rgb receives 3 floats per query.
  virtual void evaluate(const NbtfDecoder& d, const TexelQuery* queries, std::size_t count, float* rgb,
                        OutputScale scale) const = 0;
  virtual void evaluate(const NbtfDecoder& d, const UvQuery* queries, std::size_t count, float* rgb,
                        OutputScale scale) const = 0;
  // One value per latent row (3 x latentRows floats); the material is not modulated.
  virtual void decodeRows(const NbtfDecoder& d, const Direction& light, const Direction& view, float* rgb,
                          OutputScale scale, bool parallel) const = 0;
  // The decoder's terms of every latent row (3 x terms floats per row), normalized.
  virtual void decodeRowTerms(const NbtfDecoder& d, const Direction& light, const Direction& view, float* terms,
                              bool parallel) const = 0;
};

// Modulated materials: one sample's RGB from its texel's coefficients e (R, or 3R per channel)
// and its R terms f (3R floats), summed in term order. Every path uses this, so they agree bit
// for bit.
inline void combineTerms(const float* e, const float* f, int terms, int channels, float* rgb) {
  for (int c = 0; c < 3; ++c) {
    const float* ec = channels == 1 ? e : e + c;  // term k's coefficient at k x channels (+ c)
    float v = 0;
    for (int k = 0; k < terms; ++k) v += ec[k * channels] * f[3 * k + c];
    rgb[c] = v;
  }
}

// Batches below this many samples run on the calling thread: starting threads costs more.
constexpr std::size_t kMinParallelSamples = 4096;

}  // namespace nbtf::detail
