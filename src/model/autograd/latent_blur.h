// A Gaussian blur of per-texel latents over the texture, with a sigma that decays over
// training: spatial regularization of a per-texel fit, so that early steps learn what
// neighbouring texels share and the noise of single images (an 8-bit JPEG stack's blocks and
// ringing) is not fitted first (NeuMIP, Kuznetsov et al. 2021: sigma from 8 texels down, half
// life a ninth of the run). PRIVATE to src/model/ (includes torch).
#pragma once
#include <torch/torch.h>

namespace nbtf::detail {

// Below this sigma (texels) the blur is the identity: its kernel's side taps would weigh
// under 0.4% (at 0.3 texels).
constexpr double kMinLatentBlurSigma = 0.3;

// sigma at polish progress q in [0, 1]: start x 2^(-q / halfLife); 0 once below
// kMinLatentBlurSigma (or with start 0).
double latentBlurSigma(double start, double halfLife, double q);

// values [height x width, D] (texel y * width + x in row y * width + x) blurred over the
// texture by a separable Gaussian of `sigma` texels, radius ceil(3 sigma), edges replicated,
// each kernel normalized. Differentiable (torch ops); sigma 0 returns `values` itself.
torch::Tensor blurLatentImage(const torch::Tensor& values, int width, int height, double sigma);

}  // namespace nbtf::detail
