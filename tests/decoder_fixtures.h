// Shared fixtures for the decoder tests: materials built in memory and an independent
// reference evaluation of the decoder (plain loops in double precision over the layers
// exactly as the file stores them: input = latent | the direction inputs of its encoding).
#pragma once
#include <array>
#include <cmath>
#include <random>
#include <vector>

#include "codec/decoder.h"
#include "codec/nbtf_file.h"
#include "codec_fixtures.h"
#include "util/direction_planes.h"
#include "util/directions.h"

namespace nbtf::testing {

// The decoder's output (normalized: linear / alpha) for one texel, evaluated naively.
// `magnitude` (optional) receives, per channel, the same network evaluated on absolute
// values (|b| + sum |w| |x|, layer by layer): the scale float rounding errors grow with.
inline std::array<double, 3> referenceOutput(const CompressedBtf& b, int texel, const Direction& light,
                                             const Direction& view, std::array<double, 3>* magnitude = nullptr) {
  std::vector<double> x, m;
  const float* z = b.latentOfTexel(texel);
  for (int q = 0; q < b.latentDim; ++q) x.push_back(z[q]);
  float d[kMaxDecoderDirectionInputs];
  encodeDirections(b.directionEncoding, light, view, d);
  if (!b.planes.empty()) {  // the direction planes' features follow (util/direction_planes.h)
    float points[6];
    directionPlanePoints(light.unitVector(), view.unitVector(), points);
    sampleDirectionPlanes(b.planes, points, d + directionInputCount(b.directionEncoding));
  }
  if (!b.clusterPlanes.empty()) {  // then the texel's latent row's own planes
    float points[6];
    directionPlanePoints(light.unitVector(), view.unitVector(), points);
    sampleDirectionPlanes(b.clusterPlanes.resolution, b.clusterPlanes.features,
                          b.clusterPlanes.rowValues(b.latentRowOfTexel(texel)), points,
                          d + directionInputCount(b.directionEncoding) + b.planes.inputCount());
  }
  x.insert(x.end(), d, d + b.directionInputs());
  for (double xi : x) m.push_back(std::fabs(xi));
  for (const DenseLayer& layer : b.decoder.layers) {
    std::vector<double> y(layer.out), ym(layer.out);
    for (int o = 0; o < layer.out; ++o) {
      double s = layer.bias[o], sm = std::fabs(layer.bias[o]);
      for (int i = 0; i < layer.in; ++i) {
        double w = layer.weight[static_cast<std::size_t>(o) * layer.in + i];
        s += w * x[i];
        sm += std::fabs(w) * m[i];
      }
      if (layer.activation == Activation::Relu) s = std::max(s, 0.0);
      if (layer.activation == Activation::Sigmoid) s = 1 / (1 + std::exp(-s));
      y[o] = s, ym[o] = sm;
    }
    x = std::move(y), m = std::move(ym);
  }
  if (magnitude) *magnitude = {m[0], m[1], m[2]};
  return {x[0], x[1], x[2]};
}

// Tolerance for float evaluation against the double reference: a few float epsilons of
// the magnitude the sums pass through (float32 epsilon is 1.2e-7).
inline double decoderTolerance(double magnitude) { return 1e-6 + 2e-6 * magnitude; }

// A random material with a decoder of the given hidden widths (ReLU) whose widths are
// deliberately not multiples of the SIMD width. k = 0: per-texel.
inline CompressedBtf makeDecoderMaterial(int k, std::vector<int> widths = {37, 21}, int width = 7, int height = 5,
                                         unsigned seed = 11,
                                         DirectionEncoding encoding = DirectionEncoding::Stereographic,
                                         int planeFeatures = 0, int clusterPlaneFeatures = 0) {
  CompressedBtf b = makeBtf(k, width, height, 8, seed);
  std::mt19937 rng(seed + 1);
  b.directionEncoding = encoding;
  if (planeFeatures > 0) {  // random direction planes of 6 x 6 points
    b.planes.resolution = 6;
    b.planes.features = planeFeatures;
    std::normal_distribution<float> value(0, 0.5f);
    b.planes.values.resize(b.planes.valueCount());
    for (float& v : b.planes.values) v = value(rng);
  }
  if (clusterPlaneFeatures > 0) {  // random cluster planes of 4 x 4 points, one set per latent row
    b.clusterPlanes.resolution = 4;
    b.clusterPlanes.features = clusterPlaneFeatures;
    b.clusterPlanes.rows = b.latentRows;
    std::normal_distribution<float> value(0, 0.5f);
    b.clusterPlanes.values.resize(b.clusterPlanes.valueCount());
    for (float& v : b.clusterPlanes.values) v = value(rng);
  }
  b.decoder = makeDecoder(b.latentDim, std::move(widths), rng, b.directionInputs());
  // He-style scale (makeDecoder draws N(0, 0.5)), so activations stay of order 1.
  for (DenseLayer& l : b.decoder.layers)
    for (float& w : l.weight) w *= static_cast<float>(2.0 * std::sqrt(2.0 / l.in));
  if (k > 0) {  // scattered ids, not t % k
    std::uniform_int_distribution<int> id(0, k - 1);
    for (auto& i : b.ids) i = id(rng);
    for (int r = 0; r < k && r < static_cast<int>(b.ids.size()); ++r) b.ids[r] = r;  // every row used
  }
  b.holdoutImages.clear();
  return b;
}

// Like makeDecoderMaterial, with outputs mostly inside [0, 1] after x alpha (a few
// negative), so 8-bit images keep most of the information.
inline CompressedBtf makeDisplayableMaterial(int k, int width = 7, int height = 5, unsigned seed = 11) {
  CompressedBtf b = makeDecoderMaterial(k, {37, 21}, width, height, seed);
  DenseLayer& last = b.decoder.layers.back();
  for (float& w : last.weight) w *= 0.1f;
  last.bias = {0.2f, 0.25f, 0.15f};
  b.alpha = 1.5f;
  return b;
}

// A material whose decoder is smooth and monotone in the stereographic coordinates:
// RGB grows with the light's and the view's x and falls with their y, and every ReLU is
// active in the hemisphere. Along a ring (phi in [0, 90]) or a meridian (phi = 0), an
// unmeasured direction between two measured ones must decode to a value between theirs.
// Lights and views: the 81-direction hemisphere.
inline CompressedBtf makeSmoothMaterial(int k = 3, int width = 3, int height = 2) {
  CompressedBtf b = makeBtf(k, width, height, 2, 5);
  b.lights = hemisphere81();
  b.views = hemisphere81();
  b.holdoutImages.clear();
  b.alpha = 0.8f;
  // Inputs: z0, z1, lx, ly, vx, vy. Hidden units (ReLU, arguments > 0 on the unit disk):
  DenseLayer h;
  h.in = 6, h.out = 4, h.activation = Activation::Relu;
  h.weight = {0.3f, 0.0f, 0.8f, -0.5f, 0.0f, 0.0f,   // light term
              0.0f, 0.2f, 0.0f, 0.0f, 0.6f, -0.4f,   // view term
              0.1f, 0.1f, 0.3f, -0.2f, 0.3f, -0.2f,  // joint term
              0.5f, -0.4f, 0.0f, 0.0f, 0.0f, 0.0f};  // latent only
  h.bias = {1.5f, 1.2f, 1.0f, 2.0f};
  DenseLayer o;
  o.in = 4, o.out = 3, o.activation = Activation::None;
  o.weight = {0.5f, 0.2f, 0.1f, 0.1f,  //
              0.2f, 0.4f, 0.2f, 0.05f,  //
              0.1f, 0.1f, 0.6f, 0.2f};
  o.bias = {0.05f, 0.02f, 0.01f};
  b.decoder.layers = {h, o};
  for (std::size_t i = 0; i < b.latents.size(); ++i) b.latents[i] = 0.25f * static_cast<float>(i % 5) - 0.5f;
  return b;
}

// The instruction sets this CPU runs, in order (the best last).
inline std::vector<DecoderIsa> supportedIsas() {
  std::vector<DecoderIsa> out;
  for (DecoderIsa isa : {DecoderIsa::Portable, DecoderIsa::Avx2, DecoderIsa::Avx512})
    if (decoderIsaSupported(isa)) out.push_back(isa);
  return out;
}

// Measured directions of the fixture plus unmeasured ones (grazing and at the pole too).
inline std::vector<Direction> probeDirections() {
  return {{0, 0}, {15, 60}, {37.5, 200}, {10, 45}, {89.9, 300}, {90, 0}, {63.2, 359.5}};
}

}  // namespace nbtf::testing
