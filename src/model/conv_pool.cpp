#include "model/conv_pool.h"

#include <ATen/Parallel.h>

#include <algorithm>
#include <cstdint>
#include <vector>

#include "model/simd_clones.h"
#include "model/vector_kernels.h"

namespace nbtf::detail {

// ---- Vector kernels, cloned per instruction-set feature (picked at load time by the ifunc
// resolver; feature names, not CPU models, so newer CPUs get the wide clone): the loops are
// plain C++ that the compiler vectorizes for each target.

// out[l] += w0 * p[l] + w1 * p[l + 1] + w2 * p[l + 2] for l < n (p padded by one each side).
NBTF_SIMD_CLONES
void stencil3Accumulate(float* __restrict out, const float* __restrict p, int n, float w0, float w1, float w2) {
  for (int l = 0; l < n; ++l) out[l] += w0 * p[l] + w1 * p[l + 1] + w2 * p[l + 2];
}

// Max over windows of 3: y[p] = max(row[3p..3p+2]), which[p] = the winner's offset. torch's
// rule: a later value wins only if strictly greater (or NaN). Branch-free: the winner is
// data-dependent and unpredictable.
NBTF_SIMD_CLONES
void pool3(const float* __restrict row, int pooled, float* __restrict y, std::uint8_t* __restrict which) {
  for (int p = 0; p < pooled; ++p) {
    const float v0 = row[3 * p], v1 = row[3 * p + 1], v2 = row[3 * p + 2];
    const bool take1 = v1 > v0 || v1 != v1;
    const float best = take1 ? v1 : v0;
    const bool take2 = v2 > best || v2 != v2;
    y[p] = take2 ? v2 : best;
    which[p] = static_cast<std::uint8_t>(take2 ? 2 : take1 ? 1 : 0);
  }
}

// The inverse routing: padded[1 + 3p + which[p]] = g[p], every other of the length + 2
// entries 0. Returns the sum of g (the bias gradient's share).
float unpool3(const float* __restrict g, const std::uint8_t* __restrict which, int pooled, int length,
              float* __restrict padded) {
  std::fill(padded, padded + length + 2, 0.0f);
  float sum = 0;
  for (int p = 0; p < pooled; ++p) {
    padded[1 + 3 * p + which[p]] = g[p];
    sum += g[p];
  }
  return sum;
}

namespace {

// x[b] as channels x (length + 2) with a zero on each side: the convolution's padding.
void padRows(const float* x, int channels, int length, float* padded) {
  for (int c = 0; c < channels; ++c) {
    float* row = padded + static_cast<std::size_t>(c) * (length + 2);
    row[0] = row[length + 1] = 0.0f;
    std::copy(x + static_cast<std::size_t>(c) * length, x + static_cast<std::size_t>(c + 1) * length, row + 1);
  }
}

struct ConvPool3Function : torch::autograd::Function<ConvPool3Function> {
  static torch::Tensor forward(torch::autograd::AutogradContext* ctx, const torch::Tensor& input,
                               const torch::Tensor& weightIn, const torch::Tensor& biasIn) {
    torch::Tensor x = input.contiguous(), weight = weightIn.contiguous(), bias = biasIn.contiguous();
    TORCH_CHECK(x.dim() == 3 && x.scalar_type() == torch::kFloat, "convPool3: x must be float [batch, in, length]");
    TORCH_CHECK(weight.dim() == 3 && weight.size(1) == x.size(1) && weight.size(2) == 3 &&
                    weight.scalar_type() == torch::kFloat,
                "convPool3: weight must be float [out, in, 3]");
    TORCH_CHECK(bias.dim() == 1 && bias.size(0) == weight.size(0), "convPool3: bias must be [out]");
    TORCH_CHECK(x.size(2) >= 3, "convPool3: length must be at least 3");
    const int batch = static_cast<int>(x.size(0)), in = static_cast<int>(x.size(1)), length = static_cast<int>(x.size(2));
    const int out = static_cast<int>(weight.size(0)), pooled = length / 3, span = 3 * pooled;
    torch::Tensor y = torch::empty({batch, out, pooled});
    torch::Tensor which = torch::empty({batch, out, pooled}, torch::kByte);
    const float* xs = x.data_ptr<float>();
    const float* w = weight.data_ptr<float>();
    const float* bs = bias.data_ptr<float>();
    float* ys = y.data_ptr<float>();
    std::uint8_t* arg = which.data_ptr<std::uint8_t>();
    at::parallel_for(0, batch, 1, [&](std::int64_t b0, std::int64_t b1) {
      std::vector<float> padded(static_cast<std::size_t>(in) * (length + 2)), row(span);
      for (std::int64_t b = b0; b < b1; ++b) {
        padRows(xs + b * in * length, in, length, padded.data());
        for (int o = 0; o < out; ++o) {
          std::fill(row.begin(), row.end(), bs[o]);
          for (int c = 0; c < in; ++c) {
            const float* wc = w + (static_cast<std::size_t>(o) * in + c) * 3;
            stencil3Accumulate(row.data(), padded.data() + static_cast<std::size_t>(c) * (length + 2), span, wc[0],
                               wc[1], wc[2]);
          }
          const std::size_t base = (static_cast<std::size_t>(b) * out + o) * pooled;
          pool3(row.data(), pooled, ys + base, arg + base);
        }
      }
    });
    ctx->save_for_backward({x, weight, which});
    return y;
  }

  static torch::autograd::variable_list backward(torch::autograd::AutogradContext* ctx,
                                                 torch::autograd::variable_list grads) {
    auto saved = ctx->get_saved_variables();
    const torch::Tensor &x = saved[0], &weight = saved[1], &which = saved[2];
    torch::Tensor gy = grads[0].contiguous();
    const int batch = static_cast<int>(x.size(0)), in = static_cast<int>(x.size(1)), length = static_cast<int>(x.size(2));
    const int out = static_cast<int>(weight.size(0)), pooled = length / 3, span = 3 * pooled;
    const bool wantInput = ctx->needs_input_grad(0);
    torch::Tensor gx = wantInput ? torch::zeros_like(x) : torch::Tensor();
    // Weight and bias gradients per batch item, summed in item order afterwards: the result
    // does not depend on how items were split among threads.
    const int perItem = out * in * 3 + out;
    std::vector<float> partial(static_cast<std::size_t>(batch) * perItem);
    const float* xs = x.data_ptr<float>();
    const float* w = weight.data_ptr<float>();
    const float* g = gy.data_ptr<float>();
    const std::uint8_t* arg = which.data_ptr<std::uint8_t>();
    float* gxs = wantInput ? gx.data_ptr<float>() : nullptr;
    at::parallel_for(0, batch, 1, [&](std::int64_t b0, std::int64_t b1) {
      std::vector<float> padded(static_cast<std::size_t>(in) * (length + 2)), gpad(length + 2);
      for (std::int64_t b = b0; b < b1; ++b) {
        padRows(xs + b * in * length, in, length, padded.data());
        float* mine = partial.data() + b * perItem;
        for (int o = 0; o < out; ++o) {
          // The convolution's gradient: the pooled gradient at each window's winner, else 0.
          const std::size_t base = (static_cast<std::size_t>(b) * out + o) * pooled;
          mine[out * in * 3 + o] = unpool3(g + base, arg + base, pooled, length, gpad.data());
          for (int c = 0; c < in; ++c) {
            const float* xc = padded.data() + static_cast<std::size_t>(c) * (length + 2);
            float* gw = mine + (static_cast<std::size_t>(o) * in + c) * 3;
            for (int j = 0; j < 3; ++j) gw[j] = dot16(gpad.data() + 1, xc + j, span);
            if (wantInput) {
              const float* wc = w + (static_cast<std::size_t>(o) * in + c) * 3;
              // dx[m] = w0 dconv[m + 1] + w1 dconv[m] + w2 dconv[m - 1]
              stencil3Accumulate(gxs + (b * in + c) * length, gpad.data(), length, wc[2], wc[1], wc[0]);
            }
          }
        }
      }
    });
    torch::Tensor gw = torch::zeros_like(weight), gb = torch::zeros({out});
    float* gws = gw.data_ptr<float>();
    float* gbs = gb.data_ptr<float>();
    for (int b = 0; b < batch; ++b) {
      const float* mine = partial.data() + static_cast<std::size_t>(b) * perItem;
      for (int i = 0; i < out * in * 3; ++i) gws[i] += mine[i];
      for (int o = 0; o < out; ++o) gbs[o] += mine[out * in * 3 + o];
    }
    return {gx, gw, gb};
  }
};

}  // namespace

torch::Tensor convPool3(const torch::Tensor& x, const torch::Tensor& weight, const torch::Tensor& bias) {
  return ConvPool3Function::apply(x, weight, bias);
}

}  // namespace nbtf::detail
