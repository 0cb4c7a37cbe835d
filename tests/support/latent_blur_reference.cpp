#include "support/latent_blur_reference.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "model/autograd/latent_blur.h"

namespace nbtf {

double latentBlurBruteForceError(std::uint64_t seed, int width, int height, int channels, double sigma) {
  torch::manual_seed(seed);
  const torch::Tensor values = torch::randn({static_cast<std::int64_t>(width) * height, channels}, torch::kFloat64);
  const torch::Tensor blurred = detail::blurLatentImage(values, width, height, sigma);
  const int r = static_cast<int>(std::ceil(3 * sigma));
  std::vector<double> w(2 * r + 1);
  double sum = 0;
  for (int i = -r; i <= r; ++i) sum += w[i + r] = std::exp(-0.5 * i * i / (sigma * sigma));
  auto v = values.accessor<double, 2>();
  auto b = blurred.accessor<double, 2>();
  double err = 0;
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      for (int c = 0; c < channels; ++c) {
        double s = 0;
        for (int i = -r; i <= r; ++i)
          for (int j = -r; j <= r; ++j) {
            const int yy = std::clamp(y + i, 0, height - 1), xx = std::clamp(x + j, 0, width - 1);
            s += w[i + r] * w[j + r] / (sum * sum) * v[yy * width + xx][c];
          }
        err = std::max(err, std::abs(s - b[y * width + x][c]));
      }
  return err;
}

double latentBlurGradientError(std::uint64_t seed, int width, int height, int channels, double sigma) {
  torch::manual_seed(seed);
  const std::int64_t rows = static_cast<std::int64_t>(width) * height;
  torch::Tensor values = torch::randn({rows, channels}, torch::kFloat64).requires_grad_(true);
  const torch::Tensor weights = torch::randn({rows, channels}, torch::kFloat64);
  (detail::blurLatentImage(values, width, height, sigma) * weights).sum().backward();
  const torch::Tensor grad = values.grad().clone();
  torch::NoGradGuard noGrad;
  auto loss = [&](const torch::Tensor& v) {
    return (detail::blurLatentImage(v, width, height, sigma) * weights).sum().item<double>();
  };
  const double h = 1e-6;
  double err = 0;
  for (std::int64_t i = 0; i < rows; ++i)
    for (int c = 0; c < channels; ++c) {
      torch::Tensor up = values.detach().clone(), down = values.detach().clone();
      up[i][c] += h, down[i][c] -= h;
      err = std::max(err, std::abs((loss(up) - loss(down)) / (2 * h) - grad[i][c].item<double>()));
    }
  return err;
}

double latentBlurSigmaAt(double start, double halfLife, double q) { return detail::latentBlurSigma(start, halfLife, q); }

}  // namespace nbtf
