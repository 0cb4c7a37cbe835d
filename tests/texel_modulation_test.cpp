#include "codec/texel_modulation.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

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
