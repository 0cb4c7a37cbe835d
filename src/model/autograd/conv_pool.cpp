#include "model/autograd/conv_pool.h"

#include <ATen/Parallel.h>

#include <algorithm>
#include <cstdint>
#include <vector>

#include "model/kernels/conv_pool_kernels.h"
#include "model/autograd/dynamic_items.h"

namespace nbtf::detail {
namespace {

int roundUp(int n, int multiple) { return (n + multiple - 1) / multiple * multiple; }

// Windows per convolve() call: its output (at most 16 channels x 3 rows) stays in L1 for
// pooling or merging.
constexpr int kChunk = 8 * phases::kLanes;

// Scratch rows, 64-byte aligned so the phase rows start on a vector.
struct Scratch {
  std::vector<float> storage;
  float* data;
  explicit Scratch(std::size_t n) : storage(n + 16, 0.0f) {
    auto address = reinterpret_cast<std::uintptr_t>(storage.data());
    data = storage.data() + ((64 - address % 64) % 64) / sizeof(float);
  }
};

// x [channels, length] -> phase rows [channels][3][stride].
void splitChannels(const float* x, int channels, int length, int stride, float* rows) {
  for (int c = 0; c < channels; ++c)
    phases::split(x + static_cast<std::size_t>(c) * length, length, stride,
                  rows + static_cast<std::size_t>(c) * 3 * stride);
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
    const int out = static_cast<int>(weight.size(0)), pooled = length / 3;
    const int stride = phases::rowStride(length), outPadded = roundUp(out, phases::kChannelBlock);
    // Weights and bias with zero rows up to a whole channel block.
    std::vector<float> coef(static_cast<std::size_t>(outPadded) * in * 3, 0.0f), biasPadded(outPadded, 0.0f);
    std::copy(weight.data_ptr<float>(), weight.data_ptr<float>() + weight.numel(), coef.begin());
    std::copy(bias.data_ptr<float>(), bias.data_ptr<float>() + out, biasPadded.begin());
    torch::Tensor y = torch::empty({batch, out, pooled});
    torch::Tensor which = torch::empty({batch, out, pooled}, torch::kByte);
    const float* xs = x.data_ptr<float>();
    float* ys = y.data_ptr<float>();
    std::uint8_t* arg = which.data_ptr<std::uint8_t>();
    forEachItemDynamic(batch, [&](int, const auto& take) {
      // Per item, cache-resident: the input in phase rows and the convolution's.
      Scratch phaseRows(static_cast<std::size_t>(in) * 3 * stride);
      Scratch conv(static_cast<std::size_t>(outPadded) * 3 * kChunk);
      for (std::int64_t b = take(); b >= 0; b = take()) {
        splitChannels(xs + b * in * length, in, length, stride, phaseRows.data);
        for (int p0 = 0; p0 < pooled; p0 += kChunk) {
          const int windows = std::min(kChunk, pooled - p0);
          phases::convolve(phaseRows.data + p0, in, stride, coef.data(), biasPadded.data(), outPadded,
                           phases::vectorsFor(windows), conv.data, kChunk);
          for (int o = 0; o < out; ++o) {
            const std::size_t base = (static_cast<std::size_t>(b) * out + o) * pooled + p0;
            phases::pool(conv.data + static_cast<std::size_t>(o) * 3 * kChunk, kChunk, windows, ys + base, arg + base);
          }
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
    const int out = static_cast<int>(weight.size(0)), pooled = length / 3;
    const int stride = phases::rowStride(length), outPadded = roundUp(out, phases::kChannelBlock),
              inPadded = roundUp(in, phases::kChannelBlock);
    const bool wantInput = ctx->needs_input_grad(0);
    torch::Tensor gx = wantInput ? torch::empty({batch, in, length}) : torch::Tensor();
    const float* w = weight.data_ptr<float>();
    // The transposed convolution's coefficients: [c][o][t] = weight[o][c][2 - t], zero rows
    // up to a whole channel block.
    std::vector<float> coefT(static_cast<std::size_t>(inPadded) * out * 3, 0.0f);
    for (int o = 0; o < out; ++o)
      for (int c = 0; c < in; ++c)
        for (int t = 0; t < 3; ++t)
          coefT[(static_cast<std::size_t>(c) * out + o) * 3 + t] = w[(static_cast<std::size_t>(o) * in + c) * 3 + 2 - t];
    // Weight and bias gradients per batch item, summed in item order afterwards: the result
    // does not depend on which thread ran which item.
    const int perItem = outPadded * in * 3 + out;
    std::vector<float> partial(static_cast<std::size_t>(batch) * perItem);
    const float* xs = x.data_ptr<float>();
    const float* g = gy.data_ptr<float>();
    const std::uint8_t* arg = which.data_ptr<std::uint8_t>();
    float* gxs = wantInput ? gx.data_ptr<float>() : nullptr;
    forEachItemDynamic(batch, [&](int, const auto& take) {
      // The convolution's gradient in phase rows (channels past `out` stay 0), and dx's rows.
      Scratch phaseRows(static_cast<std::size_t>(in) * 3 * stride);
      Scratch gconv(static_cast<std::size_t>(outPadded) * 3 * stride);
      Scratch dx(wantInput ? static_cast<std::size_t>(inPadded) * 3 * kChunk : 0);
      for (std::int64_t b = take(); b >= 0; b = take()) {
        float* mine = partial.data() + b * perItem;
        splitChannels(xs + b * in * length, in, length, stride, phaseRows.data);
        for (int o = 0; o < out; ++o) {
          const std::size_t base = (static_cast<std::size_t>(b) * out + o) * pooled;
          mine[outPadded * in * 3 + o] =
              phases::unpool(g + base, arg + base, pooled, stride, gconv.data + static_cast<std::size_t>(o) * 3 * stride);
        }
        phases::weightGradient(gconv.data, outPadded, phaseRows.data, in, stride, phases::vectorsFor(pooled),
                               mine);
        if (wantInput) {
          // dx at 3p + j for every window p that holds a position below length.
          const int needed = (length + 2) / 3;
          for (int p0 = 0; p0 < needed; p0 += kChunk) {
            const int windows = std::min(kChunk, needed - p0);
            phases::convolve(gconv.data + p0, out, stride, coefT.data(), nullptr, inPadded, phases::vectorsFor(windows),
                             dx.data, kChunk);
            for (int c = 0; c < in; ++c)
              phases::merge(dx.data + static_cast<std::size_t>(c) * 3 * kChunk, kChunk,
                            std::min(3 * windows, length - 3 * p0), gxs + (b * in + c) * length + 3 * p0);
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
      for (int o = 0; o < out; ++o) gbs[o] += mine[outPadded * in * 3 + o];
    }
    return {gx, gw, gb};
  }
};

}  // namespace

torch::Tensor convPool3(const torch::Tensor& x, const torch::Tensor& weight, const torch::Tensor& bias) {
  return ConvPool3Function::apply(x, weight, bias);
}

}  // namespace nbtf::detail
