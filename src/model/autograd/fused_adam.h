// Adam's update as one loop per parameter tensor. PRIVATE to src/model/ (includes torch).
//
// Why: torch::optim::Adam::step runs about ten tensor operations per parameter, each
// dispatched and parallelized on its own; the encoder and decoder have 20 small
// parameter tensors, so a step of the optimizer cost a millisecond, a few percent of a
// training step, nearly all overhead. This applies the same update to the same state
// (torch's AdamParamState: step, exp_avg, exp_avg_sq), so checkpoints written by either
// are read by both.
#pragma once
#include <torch/torch.h>

namespace nbtf::detail {

// One step of `adam` (options: lr, betas, eps; weight decay 0, no amsgrad) over every
// parameter that has a gradient. Element order within a tensor does not matter (each
// element's update is independent), so the result does not depend on threads.
void fusedAdamStep(torch::optim::Adam& adam);

}  // namespace nbtf::detail
