#include "model/autograd/batch_norm.h"

#include <ATen/Parallel.h>

#include <cmath>

#include "util/simd.h"

namespace nbtf::detail {
namespace {

// ---- Row kernels (one channel of one batch item: `n` contiguous values). Partial sums in
// kAccumulators x kLanes lanes (independent FMA chains, so a row streams at the cache's pace,
// not at the adder's latency), reduced in a fixed order: the same on every run.
constexpr int kLanes = 16, kAccumulators = 4, kWide = kLanes * kAccumulators;

// Inlined into each clone: an out-of-line baseline (SSE) copy called from AVX-512 code was slow.
inline __attribute__((always_inline)) double laneTotal(const float* acc) {
  float lanes[kLanes];  // the accumulators added lane-wise first: short rows are common
  for (int k = 0; k < kLanes; ++k) lanes[k] = (acc[k] + acc[kLanes + k]) + (acc[2 * kLanes + k] + acc[3 * kLanes + k]);
  double s = 0;
  for (int k = 0; k < kLanes; ++k) s += lanes[k];
  return s;
}

NBTF_SIMD_CLONES double rowSum(const float* __restrict x, int n) {
  float acc[kWide] = {};
  int i = 0;
  for (; i + kWide <= n; i += kWide)
    for (int k = 0; k < kWide; ++k) acc[k] += x[i + k];
  for (; i + kLanes <= n; i += kLanes)  // short rows: the rest a vector at a time
    for (int k = 0; k < kLanes; ++k) acc[k] += x[i + k];
  for (; i < n; ++i) acc[i % kLanes] += x[i];
  return laneTotal(acc);
}

// sum (x - mean)^2
NBTF_SIMD_CLONES double rowSquaredDeviation(const float* __restrict x, int n, float mean) {
  float acc[kWide] = {};
  int i = 0;
  for (; i + kWide <= n; i += kWide)
    for (int k = 0; k < kWide; ++k) {
      const float d = x[i + k] - mean;
      acc[k] += d * d;
    }
  for (; i + kLanes <= n; i += kLanes)
    for (int k = 0; k < kLanes; ++k) {
      const float d = x[i + k] - mean;
      acc[k] += d * d;
    }
  for (; i < n; ++i) {
    const float d = x[i] - mean;
    acc[i % kLanes] += d * d;
  }
  return laneTotal(acc);
}

// y = (x - mean) * scale + beta
NBTF_SIMD_CLONES void rowNormalize(const float* __restrict x, int n, float mean, float scale, float beta,
                                   float* __restrict y) {
  for (int i = 0; i < n; ++i) y[i] = (x[i] - mean) * scale + beta;
}

// sum g and sum g * (x - mean)
NBTF_SIMD_CLONES void rowGradientSums(const float* __restrict g, const float* __restrict x, int n, float mean,
                                      double& sumG, double& sumGx) {
  float a[kWide] = {}, b[kWide] = {};
  int i = 0;
  for (; i + kWide <= n; i += kWide)
    for (int k = 0; k < kWide; ++k) {
      a[k] += g[i + k];
      b[k] += g[i + k] * (x[i + k] - mean);
    }
  for (; i + kLanes <= n; i += kLanes)
    for (int k = 0; k < kLanes; ++k) {
      a[k] += g[i + k];
      b[k] += g[i + k] * (x[i + k] - mean);
    }
  for (; i < n; ++i) {
    a[i % kLanes] += g[i];
    b[i % kLanes] += g[i] * (x[i] - mean);
  }
  sumG += laneTotal(a);
  sumGx += laneTotal(b);
}

// dx = k (g - meanG - (x - mean) c)
NBTF_SIMD_CLONES void rowInputGradient(const float* __restrict g, const float* __restrict x, int n, float mean,
                                       float k, float meanG, float c, float* __restrict dx) {
  for (int i = 0; i < n; ++i) dx[i] = k * (g[i] - meanG - (x[i] - mean) * c);
}

struct BatchNormFunction : torch::autograd::Function<BatchNormFunction> {
  static torch::Tensor forward(torch::autograd::AutogradContext* ctx, const torch::Tensor& input,
                               const torch::Tensor& gammaIn, const torch::Tensor& betaIn, torch::Tensor runningMean,
                               torch::Tensor runningVar, double momentum, double eps) {
    torch::Tensor x = input.contiguous(), gamma = gammaIn.contiguous(), beta = betaIn.contiguous();
    TORCH_CHECK(x.dim() == 3 && x.scalar_type() == torch::kFloat, "batchNorm: x must be float [batch, channels, length]");
    const int batch = static_cast<int>(x.size(0)), channels = static_cast<int>(x.size(1)),
              length = static_cast<int>(x.size(2));
    const std::int64_t n = static_cast<std::int64_t>(batch) * length;
    TORCH_CHECK(n > 1, "batchNorm: needs more than one value per channel");
    TORCH_CHECK(gamma.numel() == channels && beta.numel() == channels && runningMean.numel() == channels &&
                    runningVar.numel() == channels,
                "batchNorm: per-channel tensors must have one value per channel");
    torch::Tensor y = torch::empty_like(x), mean = torch::empty({channels}), invStd = torch::empty({channels});
    const float* xs = x.data_ptr<float>();
    float* ys = y.data_ptr<float>();
    float* m = mean.data_ptr<float>();
    float* is = invStd.data_ptr<float>();
    const float* gs = gamma.data_ptr<float>();
    const float* bs = beta.data_ptr<float>();
    float* rm = runningMean.data_ptr<float>();
    float* rv = runningVar.data_ptr<float>();
    auto row = [&](int b, int c) { return static_cast<std::size_t>(b * channels + c) * length; };
    at::parallel_for(0, channels, 1, [&](std::int64_t c0, std::int64_t c1) {
      for (int c = static_cast<int>(c0); c < c1; ++c) {
        double sum = 0;
        for (int b = 0; b < batch; ++b) sum += rowSum(xs + row(b, c), length);
        const float mu = static_cast<float>(sum / n);
        double ss = 0;
        for (int b = 0; b < batch; ++b) ss += rowSquaredDeviation(xs + row(b, c), length, mu);
        const double var = ss / n;
        const float inv = static_cast<float>(1.0 / std::sqrt(var + eps));
        for (int b = 0; b < batch; ++b) rowNormalize(xs + row(b, c), length, mu, inv * gs[c], bs[c], ys + row(b, c));
        m[c] = mu;
        is[c] = inv;
        rm[c] = static_cast<float>((1 - momentum) * rm[c] + momentum * mu);
        rv[c] = static_cast<float>((1 - momentum) * rv[c] + momentum * ss / (n - 1));
      }
    });
    ctx->save_for_backward({x, gamma, mean, invStd});
    return y;
  }

  static torch::autograd::variable_list backward(torch::autograd::AutogradContext* ctx,
                                                 torch::autograd::variable_list grads) {
    auto saved = ctx->get_saved_variables();
    const torch::Tensor &x = saved[0], &gamma = saved[1], &mean = saved[2], &invStd = saved[3];
    torch::Tensor g = grads[0].contiguous();
    const int batch = static_cast<int>(x.size(0)), channels = static_cast<int>(x.size(1)),
              length = static_cast<int>(x.size(2));
    const std::int64_t n = static_cast<std::int64_t>(batch) * length;
    torch::Tensor dx = torch::empty_like(x), dgamma = torch::empty({channels}), dbeta = torch::empty({channels});
    const float* xs = x.data_ptr<float>();
    const float* gsrc = g.data_ptr<float>();
    float* dxs = dx.data_ptr<float>();
    const float* gam = gamma.data_ptr<float>();
    const float* m = mean.data_ptr<float>();
    const float* is = invStd.data_ptr<float>();
    float* dg = dgamma.data_ptr<float>();
    float* db = dbeta.data_ptr<float>();
    auto row = [&](int b, int c) { return static_cast<std::size_t>(b * channels + c) * length; };
    at::parallel_for(0, channels, 1, [&](std::int64_t c0, std::int64_t c1) {
      for (int c = static_cast<int>(c0); c < c1; ++c) {
        double sumG = 0, sumGx = 0;  // sum g, sum g (x - mean)
        for (int b = 0; b < batch; ++b) rowGradientSums(gsrc + row(b, c), xs + row(b, c), length, m[c], sumG, sumGx);
        const double inv = is[c];
        db[c] = static_cast<float>(sumG);
        dg[c] = static_cast<float>(sumGx * inv);
        // dx = gamma inv (g - mean(g) - xhat mean(g xhat)), xhat = (x - mean) inv
        const float k = static_cast<float>(gam[c] * inv);
        const float meanG = static_cast<float>(sumG / n), coef = static_cast<float>(sumGx * inv * inv / n);
        for (int b = 0; b < batch; ++b)
          rowInputGradient(gsrc + row(b, c), xs + row(b, c), length, m[c], k, meanG, coef, dxs + row(b, c));
      }
    });
    return {dx, dgamma, dbeta, torch::Tensor(), torch::Tensor(), torch::Tensor(), torch::Tensor()};
  }
};

}  // namespace

torch::Tensor batchNormTrain(const torch::Tensor& x, const torch::Tensor& gamma, const torch::Tensor& beta,
                             torch::Tensor& runningMean, torch::Tensor& runningVar, torch::Tensor& numBatchesTracked,
                             double momentum, double eps) {
  // The running statistics are buffers (no gradient), updated in place by forward.
  torch::Tensor y = BatchNormFunction::apply(x, gamma, beta, runningMean, runningVar, momentum, eps);
  torch::NoGradGuard noGrad;
  numBatchesTracked.add_(1);
  return y;
}

}  // namespace nbtf::detail
