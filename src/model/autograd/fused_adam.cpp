#include "model/autograd/fused_adam.h"

#include <cmath>

#include "util/simd.h"

namespace nbtf::detail {
namespace {

// m = b1 m + c1 g; v = b2 v + c2 g^2; p -= stepSize m / (sqrt(v) / sqrt(bc2) + eps), with
// c = 1 - b computed in double like torch (1 - 0.999f in float is off by 5e-5 relative).
NBTF_SIMD_CLONES void adamUpdate(std::int64_t n, const float* __restrict g, float* __restrict m, float* __restrict v,
                                 float* __restrict p, float beta1, float c1, float beta2, float c2, float rootBias2,
                                 float eps, float stepSize) {
  for (std::int64_t i = 0; i < n; ++i) {
    const float mi = m[i] * beta1 + g[i] * c1;
    const float vi = v[i] * beta2 + g[i] * g[i] * c2;
    m[i] = mi;
    v[i] = vi;
    p[i] -= stepSize * (mi / (std::sqrt(vi) / rootBias2 + eps));
  }
}

}  // namespace

void fusedAdamStep(torch::optim::Adam& adam) {
  torch::NoGradGuard noGrad;
  for (auto& group : adam.param_groups()) {
    const auto& options = static_cast<const torch::optim::AdamOptions&>(group.options());
    TORCH_CHECK(options.weight_decay() == 0 && !options.amsgrad(), "fusedAdamStep: no weight decay or amsgrad");
    const double beta1 = std::get<0>(options.betas()), beta2 = std::get<1>(options.betas());
    for (auto& p : group.params()) {
      if (!p.grad().defined()) continue;
      TORCH_CHECK(p.is_contiguous() && p.scalar_type() == torch::kFloat, "fusedAdamStep: float parameters");
      auto& slot = adam.state()[c10::guts::to_string(p.unsafeGetTensorImpl())];
      if (!slot) {  // first step: zero moments, as torch's Adam creates them
        auto fresh = std::make_unique<torch::optim::AdamParamState>();
        fresh->step(0);
        fresh->exp_avg(torch::zeros_like(p, torch::MemoryFormat::Preserve));
        fresh->exp_avg_sq(torch::zeros_like(p, torch::MemoryFormat::Preserve));
        slot = std::move(fresh);
      }
      auto& state = static_cast<torch::optim::AdamParamState&>(*slot);
      state.step(state.step() + 1);
      const double bias1 = 1 - std::pow(beta1, state.step()), bias2 = 1 - std::pow(beta2, state.step());
      torch::Tensor g = p.grad().contiguous();
      adamUpdate(p.numel(), g.data_ptr<float>(), state.exp_avg().data_ptr<float>(),
                 state.exp_avg_sq().data_ptr<float>(), p.data_ptr<float>(), static_cast<float>(beta1),
                 static_cast<float>(1 - beta1), static_cast<float>(beta2), static_cast<float>(1 - beta2),
                 static_cast<float>(std::sqrt(bias2)), static_cast<float>(options.eps()),
                 static_cast<float>(options.lr() / bias1));
    }
  }
}

}  // namespace nbtf::detail
