#include "model/autograd/latent_blur.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace nbtf::detail {

double latentBlurSigma(double start, double halfLife, double q) {
  if (!(start > 0) || !(halfLife > 0)) return 0;
  const double sigma = start * std::exp2(-std::clamp(q, 0.0, 1.0) / halfLife);
  return sigma < kMinLatentBlurSigma ? 0 : sigma;
}

namespace {

torch::Tensor gaussianTaps(double sigma, int radius) {
  std::vector<float> taps(2 * static_cast<std::size_t>(radius) + 1);
  double sum = 0;
  for (int i = -radius; i <= radius; ++i) sum += taps[i + radius] = static_cast<float>(std::exp(-0.5 * i * i / (sigma * sigma)));
  for (float& t : taps) t = static_cast<float>(t / sum);
  return torch::from_blob(taps.data(), {static_cast<std::int64_t>(taps.size())}, torch::kFloat32).clone();
}

// One axis of the separable blur: x [1, D, H, W] convolved along `dim` (2: rows, 3: columns)
// with `taps`, each channel on its own, the edge values repeated past the border.
torch::Tensor blurAxis(const torch::Tensor& x, const torch::Tensor& taps, int dim) {
  namespace F = torch::nn::functional;
  const std::int64_t r = (taps.size(0) - 1) / 2, channels = x.size(1);
  const std::vector<std::int64_t> pad = dim == 3 ? std::vector<std::int64_t>{r, r, 0, 0} : std::vector<std::int64_t>{0, 0, r, r};
  torch::Tensor padded = F::pad(x, F::PadFuncOptions(pad).mode(torch::kReplicate));
  torch::Tensor kernel = dim == 3 ? taps.view({1, 1, 1, -1}) : taps.view({1, 1, -1, 1});
  return F::conv2d(padded, kernel.expand({channels, 1, kernel.size(2), kernel.size(3)}).contiguous(),
                   F::Conv2dFuncOptions().groups(channels));
}

}  // namespace

torch::Tensor blurLatentImage(const torch::Tensor& values, int width, int height, double sigma) {
  if (!(sigma > 0)) return values;
  TORCH_CHECK(values.dim() == 2 && values.size(0) == static_cast<std::int64_t>(width) * height,
              "blurLatentImage: values must be [width x height, D]");
  const int radius = static_cast<int>(std::ceil(3 * sigma));
  const torch::Tensor taps = gaussianTaps(sigma, radius).to(values.options());
  torch::Tensor image = values.view({height, width, values.size(1)}).permute({2, 0, 1}).unsqueeze(0);
  image = blurAxis(blurAxis(image, taps, 3), taps, 2);
  return image.squeeze(0).permute({1, 2, 0}).reshape({static_cast<std::int64_t>(width) * height, values.size(1)}).contiguous();
}

}  // namespace nbtf::detail
