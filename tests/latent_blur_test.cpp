// The latent blur schedule (model/autograd/latent_blur.h): the blur against a brute-force
// Gaussian, its gradient against finite differences, the sigma's decay.
#include <gtest/gtest.h>

#include "support/latent_blur_reference.h"

namespace nbtf {

// The taps are float (the latents are): 1e-6 on unit-variance values is their rounding; a
// wrong tap, edge or axis is off by 1e-2 or more.
TEST(LatentBlur, MatchesABruteForceGaussianWithClampedEdges) {
  EXPECT_LT(latentBlurBruteForceError(1, 7, 5, 2, 1.3), 1e-6);
  EXPECT_LT(latentBlurBruteForceError(2, 4, 9, 3, 0.8), 1e-6);
  // A kernel wider than the plane: the edge texels repeat.
  EXPECT_LT(latentBlurBruteForceError(3, 3, 2, 1, 4.0), 1e-6);
}

TEST(LatentBlur, GradientIsTheFiniteDifference) {
  EXPECT_LT(latentBlurGradientError(4, 6, 5, 2, 1.1), 1e-7);
  EXPECT_LT(latentBlurGradientError(5, 3, 4, 1, 2.5), 1e-7);
}

TEST(LatentBlur, SigmaHalvesEveryHalfLifeAndStopsBelowAThirdOfATexel) {
  EXPECT_DOUBLE_EQ(latentBlurSigmaAt(8, 1.0 / 9, 0), 8);
  EXPECT_DOUBLE_EQ(latentBlurSigmaAt(8, 1.0 / 9, 1.0 / 9), 4);
  EXPECT_DOUBLE_EQ(latentBlurSigmaAt(8, 1.0 / 9, 3.0 / 9), 1);
  EXPECT_EQ(latentBlurSigmaAt(8, 1.0 / 9, 1), 0);  // 8 / 512 texels: no blur
  EXPECT_EQ(latentBlurSigmaAt(0, 1.0 / 9, 0), 0);
  EXPECT_DOUBLE_EQ(latentBlurSigmaAt(8, 1.0 / 9, 2), 0);  // progress is clamped to [0, 1]
}

}  // namespace nbtf
