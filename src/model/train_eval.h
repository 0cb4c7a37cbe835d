// The exact per-texel RMSE of a trained model (eq. 10). PRIVATE to src/model/.
#pragma once
#include "model/autograd/decoder_backprop.h"
#include "model/training_set.h"

namespace nbtf::detail {

struct RmsError {
  double train = 0;     // over texels x training images x channels, linear / alpha
  double holdout = -1;  // same over held-out images; -1 when there are none
};

// Decodes every (group, image) once and adds the within-cluster term, so the cost is
// k x N decoder evaluations, not M x N:
//   sum_t |f - y_t|^2 = n_c |f - ybar_c|^2 + sum_t |y_t - ybar_c|^2.
RmsError evaluateRmse(const TrainingSet& set, DecoderBackprop& decoder, const torch::Tensor& latents, bool progress,
                      const float* clusterPlanes = nullptr);

}  // namespace nbtf::detail
