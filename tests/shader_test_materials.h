// Small materials of every kind the shader generator handles, with decoded values mostly in
// [0, 1] so that 8-bit sRGB comparisons keep their information (shader and viewer tests).
#pragma once
#include <fstream>
#include <iterator>
#include <random>
#include <string>

#include "codec/texel_modulation.h"
#include "decoder_fixtures.h"

namespace nbtf::testing {

// Clustered, two-octave Fourier inputs, direction planes, 2 modulation terms per channel; the
// default's hidden width (106), so the weights fill more than one row of their texture. With
// clusterPlaneFeatures > 0, each cluster also has its own planes (4 x 4 points).
inline CompressedBtf makeShaderClusteredMaterial(int clusterPlaneFeatures = 0) {
  CompressedBtf b = makeDecoderMaterial(5, {106, 106}, 9, 7, 11, DirectionEncoding::StereographicFourier2, 3,
                                        clusterPlaneFeatures);
  const int terms = 2, channels = 3;
  std::mt19937 rng(3);
  std::normal_distribution<float> normal(0.f, 0.02f);
  DenseLayer& last = b.decoder.layers.back();
  last.out = 3 * terms;
  last.weight.resize(static_cast<std::size_t>(last.in) * last.out);
  for (float& w : last.weight) w = normal(rng);
  last.bias = {0.45f, 0.35f, 0.25f, 0.05f, -0.04f, 0.03f};
  std::vector<float> raw(static_cast<std::size_t>(b.numTexels()) * terms * channels);
  for (std::size_t i = 0; i < raw.size(); ++i) {
    const int column = static_cast<int>(i % (terms * channels));
    raw[i] = column < channels ? 0.6f + 0.8f * static_cast<float>((i * 7) % 11) / 10.0f
                               : -0.5f + static_cast<float>((i * 5) % 13) / 12.0f;
  }
  b.modulation = quantizeTexelCoefficients(raw, terms, 8, channels);
  b.alpha = 1.2f;
  return b;
}

// Per-texel, stereographic + half vector, a sigmoid hidden layer.
inline CompressedBtf makeShaderPerTexelMaterial() {
  CompressedBtf b = makeDecoderMaterial(0, {24, 16}, 8, 6, 13, DirectionEncoding::StereographicHalf);
  b.decoder.layers[0].activation = Activation::Sigmoid;
  DenseLayer& last = b.decoder.layers.back();
  for (float& w : last.weight) w *= 0.1f;
  last.bias = {0.3f, 0.4f, 0.2f};
  b.alpha = 1.4f;
  return b;
}

// PCA baseline over 19 x 19 measured directions (rings 0 to 30 degrees), 4 components.
inline CompressedBtf makeShaderPcaMaterial() {
  CompressedBtf b = makePcaBtf(4, 8, 6, 21);
  b.lights.assign(hemisphere81().begin(), hemisphere81().begin() + 19);
  b.views = b.lights;
  std::mt19937 rng(5);
  std::normal_distribution<float> normal(0.f, 1.f);
  b.pcaMean.resize(3 * static_cast<std::size_t>(b.numImages()));
  for (float& m : b.pcaMean) m = 0.5f + 0.1f * normal(rng);
  b.pcaBasis.resize(b.pcaMean.size() * b.latentDim);
  for (float& x : b.pcaBasis) x = 0.05f * normal(rng);
  b.holdoutImages.clear();
  b.alpha = 0.9f;
  return b;
}

// The whole file at `path` ("" when it cannot be read).
inline std::string readText(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

}  // namespace nbtf::testing
