// Shared fixtures for the codec tests: small valid CompressedBtf values built in memory.
#pragma once
#include <filesystem>
#include <random>

#include "codec/nbtf_file.h"
#include "io/btf_names.h"
#include "io/image_io.h"
#include "model_test_material.h"

namespace nbtf::testing {

// An MLP decoder latentDim + 4 -> widths... -> 3 with random weights.
inline Mlp makeDecoder(int latentDim, std::vector<int> widths, std::mt19937& rng, int directionInputs = 4) {
  std::normal_distribution<float> normal(0.f, 0.5f);
  Mlp mlp;
  int in = latentDim + directionInputs;
  widths.push_back(3);
  for (std::size_t i = 0; i < widths.size(); ++i) {
    DenseLayer l;
    l.in = in;
    l.out = widths[i];
    l.activation = i + 1 < widths.size() ? Activation::Relu : Activation::None;
    l.weight.resize(static_cast<std::size_t>(l.in) * l.out);
    l.bias.resize(l.out);
    for (float& w : l.weight) w = normal(rng);
    for (float& b : l.bias) b = normal(rng);
    mlp.layers.push_back(std::move(l));
    in = widths[i];
  }
  return mlp;
}

// A small valid material: clustered with k rows (or per-texel when k == 0), cropped out of
// larger UTIA half-float images, 3 lights x 2 views, two hold-out images.
inline CompressedBtf makeBtf(int k, int width = 4, int height = 3, int latentDim = 8, unsigned seed = 7) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> normal(0.f, 1.f);
  CompressedBtf b;
  b.method = k > 0 ? CodecMethod::ClusteredNeural : CodecMethod::PerTexelNeural;
  b.width = width;
  b.height = height;
  b.sourceWidth = width + 10;
  b.sourceHeight = height + 20;
  b.crop = Crop{3, 5, width, height};
  b.layout = Layout::Utia;
  b.sourceSampleType = SampleType::Half;
  b.lights = {{0, 0}, {15, 0}, {15, 60}};
  b.views = {{0, 0}, {30, 30}};
  b.alpha = 1.75f;
  b.latentDim = latentDim;
  b.decoder = makeDecoder(latentDim, {6, 5}, rng);
  b.latentRows = k > 0 ? k : width * height;
  b.latents.resize(static_cast<std::size_t>(b.latentRows) * latentDim);
  for (float& z : b.latents) z = normal(rng);
  if (k > 0) {
    b.ids.resize(static_cast<std::size_t>(width) * height);
    for (std::size_t t = 0; t < b.ids.size(); ++t) b.ids[t] = static_cast<std::int32_t>(t % k);
  }
  b.holdoutImages = {1, 4};
  b.metadataJson = R"({"seed": 1, "config": {"epochs": 3}})";
  return b;
}

// A small valid PCA-baseline material with the geometry of makeBtf: C components, random
// mean, basis and coefficients, two hold-out images.
inline CompressedBtf makePcaBtf(int components = 3, int width = 4, int height = 3, unsigned seed = 11) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> normal(0.f, 1.f);
  CompressedBtf b = makeBtf(0, width, height, 8, seed);
  b.method = CodecMethod::Pca;
  b.decoder = Mlp{};
  b.latentDim = components;
  b.latentRows = width * height;
  b.latents.resize(static_cast<std::size_t>(b.latentRows) * components);
  for (float& c : b.latents) c = normal(rng);
  b.pcaMean.resize(3 * static_cast<std::size_t>(b.numImages()));
  for (float& m : b.pcaMean) m = 0.5f + 0.1f * normal(rng);
  b.pcaBasis.resize(b.pcaMean.size() * components);
  for (float& x : b.pcaBasis) x = 0.2f * normal(rng);
  b.metadataJson = R"({"seed": 1, "pca": {"components": 3}})";
  return b;
}

// The value the PCA baseline defines at a measured image (in double, normalized).
inline double pcaValue(const CompressedBtf& b, int texel, int image, int channel) {
  const std::size_t c = static_cast<std::size_t>(b.latentDim), row = 3 * static_cast<std::size_t>(image) + channel;
  double v = b.pcaMean[row];
  for (std::size_t k = 0; k < c; ++k) v += double(b.latents[texel * c + k]) * b.pcaBasis[row * c + k];
  return v;
}

// Writes the model tests' 8 x 8-texel, 9 x 9-direction synthetic material to `root` as a
// UTIA stack of float EXRs (exact values), for tests that go through the loader.
inline std::string writeTestStack(const std::string& root) {
  TestMaterial m = makeTestMaterial();
  std::vector<float> rgb(static_cast<std::size_t>(m.stack.numTexels()) * 3);
  for (int l = 0; l < m.stack.numLights(); ++l)
    for (int v = 0; v < m.stack.numViews(); ++v) {
      const Direction& light = m.stack.lights()[l];
      const Direction& view = m.stack.views()[v];
      std::filesystem::path folder = std::filesystem::path(root) / viewFolderName(view);
      std::filesystem::create_directories(folder);
      m.stack.imageLinear(m.stack.imageIndex(l, v), rgb.data());
      writeExr((folder / utiaFileName(light, view, ".exr")).string(), m.stack.width(), m.stack.height(), rgb.data(),
               /*halfFloat=*/false);
    }
  return root;
}

}  // namespace nbtf::testing
