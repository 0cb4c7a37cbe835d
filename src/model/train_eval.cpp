#include "model/train_eval.h"

#include <cmath>

#include "util/progress.h"

namespace nbtf::detail {

RmsError evaluateRmse(const TrainingSet& set, DecoderBackprop& decoder, const torch::Tensor& latents, bool progress,
                      const float* clusterPlanes) {
  torch::NoGradGuard noGrad;
  const int images = set.images(), groups = set.groups();
  // Groups per chunk: about 64k decoder rows, at least one group.
  const int chunk = std::max(1, 65536 / images);
  torch::Tensor dirsOne = torch::from_blob(const_cast<float*>(set.directions().data()), {images, set.directionWidth()}).clone();
  std::vector<int> all(images);
  for (int i = 0; i < images; ++i) all[i] = i;
  const int outputs = set.outputs();
  std::vector<float> target(static_cast<std::size_t>(images) * outputs);
  double sse[2] = {0, 0};  // [train, holdout]
  Progress bar("evaluate", groups, progress);
  for (int g0 = 0; g0 < groups; g0 += chunk) {
    const int n = std::min(chunk, groups - g0);
    torch::Tensor dirs = dirsOne.repeat({n, 1});
    if (clusterPlanes)
      for (int j = 0; j < n; ++j)
        set.writeClusterPlaneFeatures(clusterPlanes + static_cast<std::size_t>(g0 + j) * set.clusterPlaneValues(),
                                      all.data(), images,
                                      dirs.data_ptr<float>() + static_cast<std::size_t>(j) * images * set.directionWidth());
    torch::Tensor out = decoder.forward(latents.narrow(0, g0, n), dirs, images);
    const float* f = out.data_ptr<float>();
    for (int j = 0; j < n; ++j) {
      const int g = g0 + j;
      if (set.groupSize(g) == 0) continue;
      set.targets(g, all.data(), images, target.data());
      double part[2] = {0, 0};
      // With modulation the coefficients are orthonormal per cluster, so the per-texel error
      // of the terms is n_c |f - T|^2 over all outputs (model/training_set.h).
      const float* fg = f + static_cast<std::size_t>(j) * images * outputs;
      for (int i = 0; i < images; ++i) {
        double e = 0;
        for (int c = 0; c < outputs; ++c) {
          double r = static_cast<double>(fg[outputs * i + c]) - target[outputs * i + c];
          e += r * r;
        }
        part[set.isHoldout(i)] += e;
      }
      sse[0] += set.groupSize(g) * part[0];
      sse[1] += set.groupSize(g) * part[1];
    }
    bar.advance(n);
  }
  bar.finish();
  for (int i = 0; i < images; ++i) sse[set.isHoldout(i)] += set.withinSse(i);
  const double perImage = static_cast<double>(set.texels()) * 3;
  RmsError e;
  e.train = std::sqrt(sse[0] / (perImage * set.trainImages().size()));
  if (!set.holdoutImages().empty()) e.holdout = std::sqrt(sse[1] / (perImage * set.holdoutImages().size()));
  return e;
}

}  // namespace nbtf::detail
