// Oracles for the latent blur (model/autograd/latent_blur.h), kept out of the test units so
// they do not include torch.
#pragma once
#include <cstdint>

namespace nbtf {

// Largest |blurLatentImage - a brute-force 2-D Gaussian| (edges clamped, each kernel
// normalized) over random values of a width x height x channels plane, in double precision.
double latentBlurBruteForceError(std::uint64_t seed, int width, int height, int channels, double sigma);
// Largest |autograd gradient - central finite difference| of sum(weights x blurred) with
// respect to the values, over every value, in double precision.
double latentBlurGradientError(std::uint64_t seed, int width, int height, int channels, double sigma);
// detail::latentBlurSigma, for tests that do not include torch.
double latentBlurSigmaAt(double start, double halfLife, double q);

}  // namespace nbtf
