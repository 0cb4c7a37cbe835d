// A small smooth synthetic material for the model tests: 8 x 8 texels, 9 lights x 9 views,
// four material classes (diffuse albedo x cos + a per-class glossy lobe) with a per-texel
// brightness variation, so clusters have within-cluster variance. Built in memory.
#pragma once
#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

#include "io/btf_stack.h"
#include "util/directions.h"
#include "model/trainer.h"
#include "preprocess/abrdf_matrix.h"
#include "support/mlp_reference.h"

namespace nbtf::testing {

struct TestMaterial {
  BtfStack stack;
  float alpha = 1;
  MatrixXfCol perTexelInputs;      // M x 3N, log + standardized
  MatrixXfCol clusterInputs;       // k x 3N: per-cluster mean of the rows above
  std::vector<std::int32_t> ids;   // M: the material class
  int clusters = 4;

  TrainInputs perTexel() const {
    TrainInputs in;
    in.stack = &stack, in.alpha = alpha, in.encoderInputs = &perTexelInputs;
    return in;
  }
  TrainInputs clustered() const {
    TrainInputs in = perTexel();
    in.encoderInputs = &clusterInputs;
    in.ids = ids;
    return in;
  }
};

inline TestMaterial makeTestMaterial(int width = 8, int height = 8) {
  const auto& h81 = hemisphere81();
  std::vector<Direction> dirs;
  for (int i : {0, 2, 5, 9, 14, 24, 33, 50, 70}) dirs.push_back(h81[i]);
  TestMaterial m;
  m.stack = BtfStack(dirs, dirs, width, height, SampleType::Half);
  const int M = width * height, N = m.stack.numImages();
  const float albedo[4][3] = {{0.8f, 0.3f, 0.2f}, {0.2f, 0.6f, 0.3f}, {0.3f, 0.3f, 0.9f}, {0.7f, 0.7f, 0.6f}};
  const float gloss[4] = {0.0f, 0.6f, 0.2f, 1.2f};
  m.ids.resize(M);
  std::vector<float> brightness(M);
  for (int t = 0; t < M; ++t) {
    int x = t % width, y = t / width;
    m.ids[t] = (x < width / 2 ? 0 : 1) + (y < height / 2 ? 0 : 2);
    brightness[t] = 0.85f + 0.3f * (0.5f + 0.5f * std::sin(1.3f * x + 0.7f * y));
  }
  std::vector<float> rgb(static_cast<std::size_t>(M) * 3);
  for (int img = 0; img < N; ++img) {
    auto l = dirs[img / m.stack.numViews()].unitVector();
    auto v = dirs[img % m.stack.numViews()].unitVector();
    double mirror = std::max(0.0, -l[0] * v[0] - l[1] * v[1] + l[2] * v[2]);  // reflect(l) . v
    double lobe = std::pow(mirror, 4.0);
    for (int t = 0; t < M; ++t)
      for (int c = 0; c < 3; ++c) {
        int k = m.ids[t];
        double value = brightness[t] * (albedo[k][c] * l[2] * (0.6 + 0.4 * v[2]) + gloss[k] * lobe);
        rgb[3 * t + c] = static_cast<float>(value);
      }
    m.stack.setImageLinear(img, rgb.data());
  }
  // Targets are normalized by the global maximum (eq. 5).
  float lo, hi;
  m.stack.valueRange(lo, hi);
  m.alpha = hi;
  // Encoder inputs: log(x + 1), standardized per dimension (eq. 1-4).
  m.perTexelInputs.resize(M, 3 * N);
  for (int t = 0; t < M; ++t) {
    std::vector<float> a = m.stack.abrdfLinear(t);
    for (int d = 0; d < 3 * N; ++d) m.perTexelInputs(t, d) = std::log(a[d] + 1.0f);
  }
  for (int d = 0; d < 3 * N; ++d) {
    auto col = m.perTexelInputs.col(d);
    float mean = col.mean();
    float sd = std::sqrt((col.array() - mean).square().mean());
    if (sd > 0) col = (col.array() - mean) / sd;
    else col.setZero();
  }
  m.clusterInputs = MatrixXfCol::Zero(m.clusters, 3 * N);
  std::vector<int> count(m.clusters, 0);
  for (int t = 0; t < M; ++t) m.clusterInputs.row(m.ids[t]) += m.perTexelInputs.row(t), ++count[m.ids[t]];
  for (int k = 0; k < m.clusters; ++k) m.clusterInputs.row(k) /= static_cast<float>(count[k]);
  return m;
}

// RMSE (eq. 10) of predicting each image's per-channel mean over texels: the bar a trained
// model must clearly beat. Linear / alpha, over texels x images x channels.
inline double imageMeanRmse(const TestMaterial& m) {
  const int M = m.stack.numTexels(), N = m.stack.numImages();
  std::vector<float> rgb(static_cast<std::size_t>(M) * 3);
  double sse = 0;
  for (int i = 0; i < N; ++i) {
    m.stack.imageLinear(i, rgb.data());
    for (int c = 0; c < 3; ++c) {
      double mean = 0;
      for (int t = 0; t < M; ++t) mean += rgb[3 * t + c] / m.alpha;
      mean /= M;
      for (int t = 0; t < M; ++t) sse += std::pow(rgb[3 * t + c] / m.alpha - mean, 2);
    }
  }
  return std::sqrt(sse / (3.0 * M * N));
}

// The best RMSE any clustered model can reach: each texel replaced by its cluster's mean
// ABRDF (the within-cluster spread that one shared latent cannot represent).
inline double clusterFloorRmse(const TestMaterial& m) {
  const int M = m.stack.numTexels(), N = m.stack.numImages();
  std::vector<float> rgb(static_cast<std::size_t>(M) * 3);
  double sse = 0;
  for (int i = 0; i < N; ++i) {
    m.stack.imageLinear(i, rgb.data());
    std::vector<double> sum(m.clusters * 3, 0.0), count(m.clusters, 0.0);
    for (int t = 0; t < M; ++t) {
      count[m.ids[t]] += 1;
      for (int c = 0; c < 3; ++c) sum[3 * m.ids[t] + c] += rgb[3 * t + c] / m.alpha;
    }
    for (int t = 0; t < M; ++t)
      for (int c = 0; c < 3; ++c) sse += std::pow(rgb[3 * t + c] / m.alpha - sum[3 * m.ids[t] + c] / count[m.ids[t]], 2);
  }
  return std::sqrt(sse / (3.0 * M * N));
}

// The RMSE a trained result really achieves, recomputed texel by texel with the exported
// Mlp and latents (no cluster-sum shortcut): images in `imageSet` only.
inline double decodedRmse(const TestMaterial& m, const TrainResult& r, const std::vector<int>& ids,
                          const std::vector<int>& imageSet) {
  const int M = m.stack.numTexels();
  const int latent = static_cast<int>(r.latents.size() / r.latentRows);
  // The direction encoding the decoder was trained with: the one whose input count fits.
  DirectionEncoding encoding = DirectionEncoding::Stereographic;
  for (DirectionEncoding e : directionEncodings())
    if (latent + directionInputCount(e) + r.planes.inputCount() + r.clusterPlanes.inputCount() == r.decoder.inputSize())
      encoding = e;
  const int dirInputs = directionInputCount(encoding);
  double sse = 0;
  RowMatrix in(static_cast<Eigen::Index>(imageSet.size()), r.decoder.inputSize());
  for (int t = 0; t < M; ++t) {
    int g = ids.empty() ? t : ids[t];
    for (std::size_t j = 0; j < imageSet.size(); ++j) {
      int img = imageSet[j];
      for (int d = 0; d < latent; ++d) in(j, d) = r.latents[static_cast<std::size_t>(g) * latent + d];
      float d[kMaxDecoderDirectionInputs];
      const Direction& light = m.stack.lights()[img / m.stack.numViews()];
      const Direction& view = m.stack.views()[img % m.stack.numViews()];
      encodeDirections(encoding, light, view, d);
      if (!r.planes.empty()) {  // the learned planes' features follow (util/direction_planes.h)
        float points[6];
        directionPlanePoints(light.unitVector(), view.unitVector(), points);
        sampleDirectionPlanes(r.planes, points, d + dirInputs);
      }
      if (!r.clusterPlanes.empty()) {  // then the texel's cluster's own planes
        float points[6];
        directionPlanePoints(light.unitVector(), view.unitVector(), points);
        sampleDirectionPlanes(r.clusterPlanes.resolution, r.clusterPlanes.features, r.clusterPlanes.rowValues(g),
                              points, d + dirInputs + r.planes.inputCount());
      }
      const int inputs = dirInputs + r.planes.inputCount() + r.clusterPlanes.inputCount();
      for (int q = 0; q < inputs; ++q) in(j, latent + q) = d[q];
    }
    RowMatrix out = mlpForward(r.decoder, in);
    for (std::size_t j = 0; j < imageSet.size(); ++j)
      for (int c = 0; c < 3; ++c) sse += std::pow(out(j, c) - m.stack.sample(imageSet[j], t, c) / m.alpha, 2);
  }
  return std::sqrt(sse / (3.0 * M * imageSet.size()));
}

// A quick recipe for tests: Adam, small batches, a few seconds at most.
inline TrainConfig quickConfig() {
  TrainConfig c;
  c.optimizer = "adam";
  c.learningRate = 3e-3;
  c.batchSize = 1024;
  c.imagesPerInput = 64;
  c.epochs = 150;
  c.minSteps = c.minStepsPerInput = c.maxSteps = 0;  // the tests count in epochs
  c.polishFraction = 0.1;
  c.threads = 1;
  c.progress = false;
  return c;
}

}  // namespace nbtf::testing
