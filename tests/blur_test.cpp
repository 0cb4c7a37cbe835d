// Effective blur: the kernel and its eq. (5) derivative, the loss gradient, and recovery of
// a known sigma.
#include "eval/blur.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "eval/metrics.h"

namespace nbtf {
namespace {

// A textured test image with detail at several scales (deterministic).
std::vector<float> texture(int w, int h) {
  std::vector<float> img(static_cast<std::size_t>(w) * h * 3);
  unsigned state = 12345;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) {
        state = state * 1664525u + 1013904223u;
        float noise = static_cast<float>(state >> 8) / static_cast<float>(1u << 24);
        float stripes = 0.5f + 0.5f * std::sin(0.9f * x + 0.4f * y + c);
        img[(static_cast<std::size_t>(y) * w + x) * 3 + c] = 0.1f + 0.5f * noise + 0.3f * stripes;
      }
  return img;
}

TEST(Blur, Eq5DerivativeMatchesFiniteDifference) {
  for (double s : {0.4, 1.0, 2.5})
    for (double x : {0.0, 1.0, 3.0})
      for (double y : {0.0, 2.0}) {
        double h = 1e-6 * s;
        double fd = (gaussian2d(s + h, x, y) - gaussian2d(s - h, x, y)) / (2 * h);
        EXPECT_NEAR(gaussian2dDSigma(s, x, y), fd, 1e-6 * std::abs(fd) + 1e-9) << s << " " << x << " " << y;
      }
}

TEST(Blur, SeparableNormalizedKernelDerivativeIsEq5Normalized) {
  // dK/ds for K = G / sum G is (G' - K sum G') / sum G with G' from eq. (5); the separable
  // k'(x) k(y) + k(x) k'(y) must agree.
  for (double s : {0.3, 1.0, 2.5}) {
    int r = blurKernelRadius(s);
    std::vector<double> k, dk;
    normalizedKernel1d(s, r, k, dk);
    double sumG = 0, sumDG = 0;
    for (int y = -r; y <= r; ++y)
      for (int x = -r; x <= r; ++x) sumG += gaussian2d(s, x, y), sumDG += gaussian2dDSigma(s, x, y);
    double kSum = 0;
    for (int y = -r; y <= r; ++y)
      for (int x = -r; x <= r; ++x) {
        double K = gaussian2d(s, x, y) / sumG;
        double dK = (gaussian2dDSigma(s, x, y) - K * sumDG) / sumG;
        EXPECT_NEAR(k[x + r] * k[y + r], K, 1e-12);
        EXPECT_NEAR(dk[x + r] * k[y + r] + k[x + r] * dk[y + r], dK, 1e-10);
        kSum += k[x + r] * k[y + r];
      }
    EXPECT_NEAR(kSum, 1.0, 1e-12);
  }
}

TEST(Blur, BlurKeepsConstantImagesAndSmoothsDetail) {
  const int w = 9, h = 7;
  std::vector<float> flat(w * h * 3, 0.37f), out(flat.size());
  for (BlurBorder b : {BlurBorder::Clamp, BlurBorder::Wrap}) {
    gaussianBlur(flat.data(), w, h, 1.7, b, out.data());
    for (float v : out) EXPECT_NEAR(v, 0.37f, 1e-6f);
  }
  // Wrap-around preserves the image mean exactly (every texel's weight is spread, none lost).
  auto tex = texture(w, h);
  gaussianBlur(tex.data(), w, h, 1.2, BlurBorder::Wrap, out.data());
  double a = 0, b = 0, varA = 0, varB = 0;
  for (std::size_t i = 0; i < tex.size(); ++i) a += tex[i], b += out[i];
  EXPECT_NEAR(a, b, 1e-3);
  a /= tex.size(), b /= tex.size();
  for (std::size_t i = 0; i < tex.size(); ++i) varA += (tex[i] - a) * (tex[i] - a), varB += (out[i] - b) * (out[i] - b);
  EXPECT_LT(varB, 0.5 * varA);
}

TEST(Blur, LossGradientMatchesFiniteDifference) {
  const int w = 20, h = 16;
  auto ref = texture(w, h);
  std::vector<float> rec(ref.size());
  gaussianBlur(ref.data(), w, h, 1.3, BlurBorder::Clamp, rec.data());
  for (double s : {0.6, 1.1, 2.2}) {
    double grad = 0;
    blurLoss(ref.data(), rec.data(), w, h, 0.8f, s, BlurBorder::Clamp, &grad);
    // Stay inside one kernel radius (ceil(4 s) constant) for the difference quotient.
    double e = 1e-5;
    double fd = (blurLoss(ref.data(), rec.data(), w, h, 0.8f, s + e, BlurBorder::Clamp, nullptr) -
                 blurLoss(ref.data(), rec.data(), w, h, 0.8f, s - e, BlurBorder::Clamp, nullptr)) /
                (2 * e);
    EXPECT_NEAR(grad, fd, 1e-4 * std::abs(fd) + 1e-10) << "sigma " << s;
    EXPECT_EQ(grad < 0, s < 1.3) << "gradient points toward the true sigma";
  }
}

// (true sigma, border, Adam start: 0 = coarse grid). Fixed starts away from the answer make
// the gradient descent itself do the work (1.0 and 2.5 are also grid points).
class BlurRecovery : public ::testing::TestWithParam<std::tuple<double, BlurBorder, double>> {};

TEST_P(BlurRecovery, RecoversAKnownSigma) {
  auto [sigma, border, start] = GetParam();
  const int w = 48, h = 40;
  auto ref = texture(w, h);
  std::vector<float> rec(ref.size());
  gaussianBlur(ref.data(), w, h, sigma, border, rec.data());
  BlurOptions o;
  o.border = border;
  o.startSigma = start;
  BlurEstimate e = estimateBlur(ref.data(), rec.data(), w, h, 1.0f, o);
  EXPECT_NEAR(e.sigma, sigma, 0.05 * sigma) << "start " << e.initialSigma << ", " << e.iterations << " iterations";
  EXPECT_TRUE(e.converged);
  EXPECT_GT(e.rmseBefore, 0.02);
  EXPECT_LT(e.rmseAfter, 0.1 * e.rmseBefore);
  EXPECT_NEAR(e.rmseBefore, rmseLinear(ref.data(), rec.data(), ref.size(), 1.0f), 1e-12);
}

INSTANTIATE_TEST_SUITE_P(Sigmas, BlurRecovery,
                         ::testing::Values(std::make_tuple(1.0, BlurBorder::Clamp, 0.0),
                                           std::make_tuple(2.5, BlurBorder::Clamp, 0.0),
                                           std::make_tuple(1.0, BlurBorder::Clamp, 1.6),
                                           std::make_tuple(2.5, BlurBorder::Clamp, 1.6),
                                           std::make_tuple(1.37, BlurBorder::Clamp, 0.0),
                                           std::make_tuple(1.7, BlurBorder::Wrap, 0.0)));

TEST(Blur, IdenticalImagesGiveSigmaNearZeroWithoutNaN) {
  const int w = 16, h = 16;
  auto ref = texture(w, h);
  BlurEstimate e = estimateBlur(ref.data(), ref.data(), w, h, 1.0f);
  EXPECT_TRUE(std::isfinite(e.sigma));
  EXPECT_LT(e.sigma, 0.3);
  EXPECT_EQ(e.rmseBefore, 0.0);
  EXPECT_EQ(e.rmseAfter, 0.0);
  EXPECT_TRUE(e.converged);
}

TEST(Blur, AFlatReconstructionStopsAtTheUpperBound) {
  // No detail at all: the best blur is as wide as allowed (a quarter of the 32-texel side),
  // and the optimizer stops there instead of pushing against the bound until the cap.
  // (Wrap-around: a wide wrapped blur tends to the mean; a clamped one does not.)
  const int w = 32, h = 24;
  auto ref = texture(w, h);
  std::vector<float> flat(ref.size());
  for (int c = 0; c < 3; ++c) {
    double mean = 0;
    for (std::size_t i = c; i < ref.size(); i += 3) mean += ref[i];
    mean /= w * h;
    for (std::size_t i = c; i < flat.size(); i += 3) flat[i] = static_cast<float>(mean);
  }
  BlurOptions o;
  o.border = BlurBorder::Wrap;
  BlurEstimate e = estimateBlur(ref.data(), flat.data(), w, h, 1.0f, o);
  EXPECT_TRUE(e.atUpperBound);
  EXPECT_EQ(e.upperBound, 8.0);
  EXPECT_NEAR(e.sigma, 8.0, 1e-9);
  EXPECT_TRUE(e.converged);
  EXPECT_LT(e.iterations, 100);
  EXPECT_LT(e.rmseAfter, e.rmseBefore);
}

TEST(Blur, NoisyReconstructionIsNotMistakenForBlur) {
  // Noise added to an unblurred image: the best blur is (near) none.
  const int w = 32, h = 32;
  auto ref = texture(w, h);
  std::vector<float> rec(ref);
  unsigned state = 99;
  for (auto& v : rec) {
    state = state * 1664525u + 1013904223u;
    v += 0.01f * (static_cast<float>(state >> 8) / (1u << 24) - 0.5f);
  }
  BlurEstimate e = estimateBlur(ref.data(), rec.data(), w, h, 1.0f);
  EXPECT_LT(e.sigma, 0.35);
  EXPECT_LE(e.rmseAfter, e.rmseBefore + 1e-12);
}

}  // namespace
}  // namespace nbtf
