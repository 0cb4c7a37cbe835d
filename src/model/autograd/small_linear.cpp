#include "model/autograd/small_linear.h"

#include <ATen/Parallel.h>

#include "model/kernels/vector_kernels.h"

namespace nbtf::detail {
namespace {

struct SmallLinearFunction : torch::autograd::Function<SmallLinearFunction> {
  static torch::Tensor forward(torch::autograd::AutogradContext* ctx, const torch::Tensor& input,
                               const torch::Tensor& weightIn, const torch::Tensor& biasIn) {
    torch::Tensor x = input.contiguous(), weight = weightIn.contiguous(), bias = biasIn.contiguous();
    TORCH_CHECK(x.dim() == 2 && x.scalar_type() == torch::kFloat, "smallLinear: x must be float [batch, in]");
    TORCH_CHECK(weight.dim() == 2 && weight.size(1) == x.size(1) && weight.scalar_type() == torch::kFloat,
                "smallLinear: weight must be float [out, in]");
    TORCH_CHECK(bias.dim() == 1 && bias.size(0) == weight.size(0), "smallLinear: bias must be [out]");
    const int batch = static_cast<int>(x.size(0)), in = static_cast<int>(x.size(1)),
              out = static_cast<int>(weight.size(0));
    torch::Tensor y = torch::empty({batch, out});
    const float* xs = x.data_ptr<float>();
    const float* w = weight.data_ptr<float>();
    const float* b = bias.data_ptr<float>();
    float* ys = y.data_ptr<float>();
    at::parallel_for(0, batch, 1, [&](std::int64_t b0, std::int64_t b1) {
      for (std::int64_t r = b0; r < b1; ++r)
        for (int o = 0; o < out; ++o)
          ys[r * out + o] = b[o] + dot16(xs + r * in, w + static_cast<std::size_t>(o) * in, in);
    });
    ctx->save_for_backward({x, weight});
    return y;
  }

  static torch::autograd::variable_list backward(torch::autograd::AutogradContext* ctx,
                                                 torch::autograd::variable_list grads) {
    auto saved = ctx->get_saved_variables();
    const torch::Tensor &x = saved[0], &weight = saved[1];
    torch::Tensor gy = grads[0].contiguous();
    const int batch = static_cast<int>(x.size(0)), in = static_cast<int>(x.size(1)),
              out = static_cast<int>(weight.size(0));
    const float* xs = x.data_ptr<float>();
    const float* w = weight.data_ptr<float>();
    const float* g = gy.data_ptr<float>();
    torch::Tensor gx, gw = torch::zeros_like(weight), gb = torch::zeros({out});
    float* gws = gw.data_ptr<float>();
    float* gbs = gb.data_ptr<float>();
    // Each output row is one thread's, summed in a fixed order: deterministic.
    at::parallel_for(0, out, 1, [&](std::int64_t o0, std::int64_t o1) {
      for (std::int64_t o = o0; o < o1; ++o)
        for (int r = 0; r < batch; ++r) {
          axpy(g[r * out + o], xs + static_cast<std::size_t>(r) * in, gws + o * in, in);
          gbs[o] += g[r * out + o];
        }
    });
    if (ctx->needs_input_grad(0)) {
      gx = torch::zeros_like(x);
      float* gxs = gx.data_ptr<float>();
      at::parallel_for(0, batch, 1, [&](std::int64_t b0, std::int64_t b1) {
        for (std::int64_t r = b0; r < b1; ++r)
          for (int o = 0; o < out; ++o) axpy(g[r * out + o], w + static_cast<std::size_t>(o) * in, gxs + r * in, in);
      });
    }
    return {gx, gw, gb};
  }
};

}  // namespace

torch::Tensor smallLinear(const torch::Tensor& x, const torch::Tensor& weight, const torch::Tensor& bias) {
  return SmallLinearFunction::apply(x, weight, bias);
}

}  // namespace nbtf::detail
