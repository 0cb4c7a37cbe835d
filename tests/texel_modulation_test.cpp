#include "codec/texel_modulation.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>

#include "codec/nbtf_format.h"
#include "test_util.h"
#include "util/error.h"

namespace nbtf {
namespace {

std::vector<float> randomCoefficients(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> dist(1.0f, 0.4f);
  std::vector<float> f(n);
  for (float& x : f) x = dist(rng);
  return f;
}

TEST(TexelModulation, QuantizationErrorIsWithinHalfAStep) {
  for (int bits : {4, 6, 8, 12}) {
    for (int terms : {1, 3}) {
      std::vector<float> a = randomCoefficients(300 * terms, 5 + bits);
      TexelModulation m = quantizeTexelCoefficients(a, terms, bits);
      ASSERT_EQ(m.codes.size(), a.size());
      for (int r = 0; r < terms; ++r) {
        const double step = (static_cast<double>(m.maximum[r]) - m.minimum[r]) / ((1 << bits) - 1);
        for (std::size_t t = 0; t < 300; ++t) {
          double back = dequantizeTexelCoefficient(m, r, m.codes[t * terms + r]);
          EXPECT_LE(std::fabs(back - a[t * terms + r]), 0.5 * step + 1e-6) << "bits " << bits << " terms " << terms;
        }
      }
    }
  }
}

TEST(TexelModulation, BadInputIsRefused) {
  EXPECT_THROW(quantizeTexelCoefficients({1.0f, NAN}, 1, 8), Error);
  EXPECT_THROW(quantizeTexelCoefficients({1.0f, 2.0f}, 1, 17), Error);
  EXPECT_THROW(quantizeTexelCoefficients({1.0f, 2.0f}, 9, 8), Error);
  EXPECT_THROW(quantizeTexelCoefficients({1.0f, 2.0f, 3.0f}, 2, 8), Error);
  EXPECT_THROW(quantizeTexelCoefficients({1.0f, 2.0f, 3.0f, 4.0f}, 1, 8, 2), Error);  // channels 1 or 3
  EXPECT_THROW(quantizeTexelCoefficients({1.0f, 2.0f, 3.0f, 4.0f}, 1, 8, 3), Error);  // not texels x 3
  // A constant term quantizes to code 0 and decodes to its value.
  TexelModulation m = quantizeTexelCoefficients({2.5f, 2.5f, 2.5f}, 1, 8);
  EXPECT_EQ(dequantizeTexelCoefficient(m, 0, m.codes[1]), 2.5f);
}

TEST(TexelModulation, OrthonormalizedCoefficientsAreOrthonormalPerCluster) {
  const int texels = 240, clusters = 7;
  std::vector<std::int32_t> ids(texels);
  for (int t = 0; t < texels; ++t) ids[t] = (t * 5 + t / 13) % clusters;
  for (int terms : {1, 2, 3}) {
    std::vector<float> a = randomCoefficients(texels * terms, 9);
    std::vector<float> e = orthonormalizeTexelCoefficients(a, terms, ids, clusters);
    ASSERT_EQ(e.size(), static_cast<std::size_t>(texels) * terms);
    for (int g = 0; g < clusters; ++g)
      for (int r = 0; r < terms; ++r)
        for (int q = 0; q < terms; ++q) {
          double dot = 0, n = 0;
          for (int t = 0; t < texels; ++t)
            if (ids[t] == g) dot += double(e[t * terms + r]) * e[t * terms + q], n += 1;
          EXPECT_NEAR(dot / n, r == q ? 1.0 : 0.0, 1e-5) << "cluster " << g << " terms " << r << "," << q;
        }
    // One term: the ratios within a cluster are kept (a brightness factor).
    if (terms == 1)
      for (int t = 1; t < texels; ++t)
        if (ids[t] == ids[0]) EXPECT_NEAR(e[t] / e[0], a[t] / a[0], 1e-5);
  }
}

// Per-channel coefficients (texels x terms x 3): each channel's columns are orthonormal per
// cluster on their own, whatever the other channels hold, and each column has its own range.
TEST(TexelModulation, PerChannelColumnsAreOrthonormalizedAndQuantizedApart) {
  const int texels = 240, clusters = 7, channels = 3;
  std::vector<std::int32_t> ids(texels);
  for (int t = 0; t < texels; ++t) ids[t] = (t * 5 + t / 13) % clusters;
  for (int terms : {1, 2}) {
    const int columns = terms * channels;
    std::vector<float> a = randomCoefficients(texels * columns, 11);
    for (int t = 0; t < texels; ++t) a[t * columns + 2] *= 4.0f;  // channel 2 of term 0: a wider range
    std::vector<float> e = orthonormalizeTexelCoefficients(a, terms, ids, clusters, channels);
    ASSERT_EQ(e.size(), a.size());
    for (int c = 0; c < channels; ++c) {
      // The same as orthonormalizing that channel's columns alone.
      std::vector<float> alone(static_cast<std::size_t>(texels) * terms);
      for (int t = 0; t < texels; ++t)
        for (int r = 0; r < terms; ++r) alone[t * terms + r] = a[t * columns + r * channels + c];
      std::vector<float> want = orthonormalizeTexelCoefficients(alone, terms, ids, clusters);
      for (int t = 0; t < texels; ++t)
        for (int r = 0; r < terms; ++r)
          ASSERT_EQ(e[t * columns + r * channels + c], want[t * terms + r]) << "channel " << c << " term " << r;
    }
    TexelModulation m = quantizeTexelCoefficients(a, terms, 8, channels);
    EXPECT_EQ(m.channels, channels);
    EXPECT_EQ(m.columns(), columns);
    ASSERT_EQ(m.codes.size(), a.size());
    EXPECT_GT(m.maximum[2] - m.minimum[2], 3.0f * (m.maximum[1] - m.minimum[1]));
    const std::vector<float> back = dequantizeTexelCoefficients(m);
    for (std::size_t i = 0; i < a.size(); ++i) {
      const int column = static_cast<int>(i % columns);
      const double step = (static_cast<double>(m.maximum[column]) - m.minimum[column]) / 255;
      if (a[i] >= m.minimum[column] && a[i] <= m.maximum[column])
        EXPECT_LE(std::fabs(back[i] - a[i]), 0.5 * step + 1e-6) << i;
    }
  }
  EXPECT_THROW(orthonormalizeTexelCoefficients(std::vector<float>(texels * 2), 1, ids, clusters, 3), Error);
}

TEST(TexelModulation, DecodingUsesTheDequantizedCodesAsTheyAre) {
  std::vector<float> a = {0.5f, -1.0f, 2.0f, 0.25f, 1.5f, 0.0f, 3.0f, 1.0f, 2.5f, -0.5f};
  TexelModulation m = quantizeTexelCoefficients(a, 2, 12);
  std::vector<float> e = dequantizeTexelCoefficients(m);
  ASSERT_EQ(e.size(), a.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(e[i], dequantizeTexelCoefficient(m, static_cast<int>(i % 2), m.codes[i]));
    EXPECT_NEAR(e[i], a[i], 1e-3);
  }
}

// Colour factors whose channels share most of their variation (a brightness factor) plus a
// little colour of their own: texels x terms x 3.
std::vector<float> correlatedColourFactors(int texels, int terms, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> bright(1.0f, 0.3f), tint(0.0f, 0.02f);
  std::vector<float> a(static_cast<std::size_t>(texels) * terms * 3);
  for (int t = 0; t < texels; ++t)
    for (int r = 0; r < terms; ++r) {
      const float b = bright(rng) * (r + 1);
      for (int c = 0; c < 3; ++c) a[(t * terms + r) * 3 + c] = b * (0.8f + 0.2f * c) + tint(rng);
    }
  return a;
}

TEST(TexelModulation, PrincipalAxesDiagonalizeASymmetricMatrix) {
  const std::array<std::array<double, 9>, 4> cases = {{
      {4, 1, 0.5, 1, 3, 0.2, 0.5, 0.2, 1},
      {1, 0, 0, 0, 1, 0, 0, 0, 1},        // already diagonal, equal eigenvalues
      {2, 2, 2, 2, 2, 2, 2, 2, 2},        // rank one
      {1e-6, 3e-7, 0, 3e-7, 2e-6, 1e-7, 0, 1e-7, 5e-7},
  }};
  for (const auto& a : cases) {
    const std::array<double, 9> v = principalAxes3(a);
    double previous = INFINITY;
    for (int k = 0; k < 3; ++k) {
      // A v_k = lambda_k v_k, lambda_k = v_k^T A v_k, in decreasing order; unit, orthogonal columns.
      double lambda = 0, scale = 0;
      for (int i = 0; i < 9; ++i) scale = std::max(scale, std::fabs(a[i]));
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) lambda += v[3 * i + k] * a[3 * i + j] * v[3 * j + k];
      for (int i = 0; i < 3; ++i) {
        double av = 0;
        for (int j = 0; j < 3; ++j) av += a[3 * i + j] * v[3 * j + k];
        EXPECT_NEAR(av, lambda * v[3 * i + k], 1e-12 * scale + 1e-300);
      }
      EXPECT_LE(lambda, previous + 1e-12 * scale);
      previous = lambda;
      for (int l = 0; l < 3; ++l) {
        double dot = 0;
        for (int i = 0; i < 3; ++i) dot += v[3 * i + k] * v[3 * i + l];
        EXPECT_NEAR(dot, k == l ? 1.0 : 0.0, 1e-12);
      }
      int largest = 0;
      for (int i = 1; i < 3; ++i)
        if (std::fabs(v[3 * i + k]) > std::fabs(v[3 * largest + k])) largest = i;
      EXPECT_GT(v[3 * largest + k], 0.0);
    }
  }
}

TEST(TexelModulation, DecorrelatedCodesRotateBackWithinTheirStep) {
  const int texels = 2000;
  for (int terms : {1, 2}) {
    const int columns = 3 * terms;
    const std::vector<float> a = correlatedColourFactors(texels, terms, 7 + terms);
    const TexelModulation m = quantizeTexelCoefficients(a, terms, 6, 3, ModulationCodes::Decorrelated);
    EXPECT_TRUE(m.decorrelated);
    ASSERT_EQ(m.codes.size(), a.size());
    const TexelModulation linear = quantizeTexelCoefficients(a, terms, 6, 3);
    const std::vector<float> back = dequantizeTexelCoefficients(m), backLinear = dequantizeTexelCoefficients(linear);
    for (int r = 0; r < terms; ++r) {
      // One step for the term's three columns: the mean of the linear codes' steps.
      const double step = (static_cast<double>(m.maximum[3 * r]) - m.minimum[3 * r]) / ((1 << m.bits) - 1);
      double linearSteps = 0;
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR((static_cast<double>(m.maximum[3 * r + c]) - m.minimum[3 * r + c]) / ((1 << m.bits) - 1), step,
                    1e-6 * step);
        linearSteps += (static_cast<double>(linear.maximum[3 * r + c]) - linear.minimum[3 * r + c]) / 63;
      }
      EXPECT_NEAR(step, linearSteps / 3, 1e-5 * step);
      // Within the codes' range every rotated value is within half a step, so a channel within
      // sqrt(3) / 2 steps; the squared error about that of the linear codes.
      double squared = 0, squaredLinear = 0;
      int inside = 0;
      for (int t = 0; t < texels; ++t) {
        double err = 0;
        for (int c = 0; c < 3; ++c) {
          const std::size_t i = static_cast<std::size_t>(t) * columns + 3 * r + c;
          err += (back[i] - a[i]) * (back[i] - a[i]);
          squaredLinear += (backLinear[i] - a[i]) * (backLinear[i] - a[i]);
        }
        bool within = true;
        for (int k = 0; k < 3; ++k) {
          double y = 0;
          for (int c = 0; c < 3; ++c)
            y += m.rotation[9 * r + 3 * c + k] * a[static_cast<std::size_t>(t) * columns + 3 * r + c];
          within = within && y >= m.minimum[3 * r + k] && y <= m.maximum[3 * r + k];
        }
        if (within) {
          ++inside;
          EXPECT_LE(std::sqrt(err), std::sqrt(3.0) / 2 * step + 1e-5) << "texel " << t;
        }
        squared += err;
      }
      EXPECT_GT(inside, texels * 99 / 100);
      EXPECT_LT(squared, 1.5 * squaredLinear);
    }
    // What it is for: the same error in fewer bytes than per-channel codes.
    EXPECT_LT(format::codedModulation(m, true).size(), format::codedModulation(linear, true).size());
    // The first axis is the brightness direction (0.8, 1, 1.2) / |.|.
    const double n = std::sqrt(0.64 + 1 + 1.44);
    EXPECT_NEAR(m.rotation[0], 0.8 / n, 0.01);
    EXPECT_NEAR(m.rotation[3], 1.0 / n, 0.01);
    EXPECT_NEAR(m.rotation[6], 1.2 / n, 0.01);
  }
  EXPECT_THROW(quantizeTexelCoefficients({1.0f, 2.0f}, 1, 6, 1, ModulationCodes::Decorrelated), Error);
  // A constant term codes as 0 and decodes to its value (to float rounding through the rotation).
  const TexelModulation c =
      quantizeTexelCoefficients({2.f, 1.f, 0.5f, 2.f, 1.f, 0.5f}, 1, 6, 3, ModulationCodes::Decorrelated);
  const std::vector<float> cb = dequantizeTexelCoefficients(c);
  for (std::size_t i = 0; i < cb.size(); ++i) EXPECT_NEAR(cb[i], (i % 3 == 0 ? 2.f : i % 3 == 1 ? 1.f : 0.5f), 1e-6);
}

TEST(TexelModulation, DependentColumnsBecomeZero) {
  // Cluster 0 has one texel (a second term adds nothing), cluster 1 has a second column that
  // is twice the first.
  std::vector<std::int32_t> ids = {0, 1, 1, 1};
  std::vector<float> a = {3.0f, 7.0f, 1.0f, 2.0f, 2.0f, 4.0f, 3.0f, 6.0f};
  std::vector<float> e = orthonormalizeTexelCoefficients(a, 2, ids, 2);
  EXPECT_NEAR(e[0], 1.0f, 1e-6);  // sqrt(1) x unit
  EXPECT_EQ(e[1], 0.0f);
  for (int t = 1; t < 4; ++t) EXPECT_EQ(e[2 * t + 1], 0.0f);
  double sq = 0;
  for (int t = 1; t < 4; ++t) sq += double(e[2 * t]) * e[2 * t];
  EXPECT_NEAR(sq, 3.0, 1e-5);
}

}  // namespace
}  // namespace nbtf
