#include "codec/pca_model.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "util/error.h"

namespace nbtf {
namespace {

double weightOf(const std::vector<ImageWeight>& w, int image) {
  for (const ImageWeight& x : w)
    if (x.image == image) return x.weight;
  return 0;
}

double weightSum(const std::vector<ImageWeight>& w) {
  return std::accumulate(w.begin(), w.end(), 0.0, [](double s, const ImageWeight& x) { return s + x.weight; });
}

TEST(PcaInterpolation, MeasuredPairGetsWeightOneAlone) {
  const auto& h = hemisphere81();
  DirectionInterpolator interp(h, h);
  for (int image : {0, 1, 82, 6560, 40 * 81 + 17}) {
    auto w = interp.weights(h[image / 81], h[image % 81]);
    ASSERT_EQ(w.size(), 1u) << image;
    EXPECT_EQ(w[0].image, image);
    EXPECT_EQ(w[0].weight, 1.0);
  }
  // phi = 360 is the same direction as phi = 0.
  auto w = interp.weights(Direction{15, 360}, Direction{30, 0});
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(w[0].image, 1 * 81 + 7);
}

TEST(PcaInterpolation, UnmeasuredPairBlendsItsNearestNeighboursConvexly) {
  const auto& h = hemisphere81();
  DirectionInterpolator interp(h, h);
  // Light halfway between (15, 0) and (15, 60) on the first ring, view measured.
  auto w = interp.weights(Direction{15, 30}, h[20]);
  ASSERT_GE(w.size(), 2u);
  EXPECT_LE(w.size(), static_cast<std::size_t>(kPcaNeighbours));
  EXPECT_NEAR(weightSum(w), 1.0, 1e-12);
  for (const ImageWeight& x : w) EXPECT_GT(x.weight, 0);
  // The two equidistant lights at the same view share the largest weight.
  const int a = 1 * 81 + 20, b = 2 * 81 + 20;
  EXPECT_NEAR(weightOf(w, a), weightOf(w, b), 1e-12);
  EXPECT_GT(weightOf(w, a), 0.3);
  EXPECT_EQ(std::max(weightOf(w, a), weightOf(w, b)), w[0].weight);
}

TEST(PcaInterpolation, WeightsAreContinuousAcrossNeighbourChanges) {
  // Sweep the light along an arc: the blended weight of every image changes gradually
  // (no jump where the set of the K nearest changes), and it ends at a measured pair.
  const auto& h = hemisphere81();
  DirectionInterpolator interp(h, h);
  std::vector<double> previous(81 * 81, 0.0);
  double largestStep = 0;
  for (int s = 0; s <= 400; ++s) {
    Direction light{5 + 10 * s / 400.0, 40.0 + 20 * s / 400.0};  // ends at (15, 60) = light 2
    auto w = interp.weights(light, h[3]);
    std::vector<double> now(81 * 81, 0.0);
    for (const ImageWeight& x : w) now[static_cast<std::size_t>(x.image)] = x.weight;
    if (s > 0)
      for (std::size_t i = 0; i < now.size(); ++i) largestStep = std::max(largestStep, std::fabs(now[i] - previous[i]));
    previous = now;
  }
  EXPECT_LT(largestStep, 0.05);
  EXPECT_NEAR(previous[2 * 81 + 3], 1.0, 1e-12);
}

TEST(PcaInterpolation, MaskedImagesAreNeverUsed) {
  const auto& h = hemisphere81();
  std::vector<std::uint8_t> usable(81 * 81, 1);
  const int held = 5 * 81 + 9;
  usable[held] = 0;
  DirectionInterpolator interp(h, h, usable);
  auto w = interp.weights(h[5], h[9]);  // exactly the held-out pair
  EXPECT_GE(w.size(), 2u);
  EXPECT_EQ(weightOf(w, held), 0.0);
  EXPECT_NEAR(weightSum(w), 1.0, 1e-12);
  // Its nearest usable neighbours share its light or its view.
  EXPECT_TRUE(w[0].image / 81 == 5 || w[0].image % 81 == 9) << w[0].image;
  EXPECT_THROW(DirectionInterpolator(h, h, std::vector<std::uint8_t>(81 * 81, 0)), Error);
  EXPECT_THROW(DirectionInterpolator(h, h, std::vector<std::uint8_t>(10, 1)), Error);
}

TEST(PcaInterpolation, FewerImagesThanNeighboursStillInterpolate) {
  // 3 lights x 1 view: inverse-distance weights over all three.
  std::vector<Direction> lights = {{0, 0}, {30, 0}, {60, 0}}, views = {{0, 0}};
  DirectionInterpolator interp(lights, views);
  auto w = interp.weights(Direction{15, 0}, Direction{0, 0});
  ASSERT_EQ(w.size(), 3u);
  EXPECT_NEAR(weightOf(w, 0), weightOf(w, 1), 1e-12);
  EXPECT_NEAR(weightOf(w, 0) / weightOf(w, 2), 9.0, 1e-9);  // 1/15^2 : 1/45^2
}

TEST(PcaInterpolation, CombineCopiesMeasuredRowsAndBlendsOthers) {
  // 2 images, C = 2: mean 6 floats, basis 6 rows x 2.
  const std::vector<float> mean = {1, 2, 3, 10, 20, 30};
  const std::vector<float> basis = {0.1f, 0.2f, 0.3f, 0.4f, 0.5f, 0.6f, 1, 2, 3, 4, 5, 6};
  float m[3], b[6];
  combinePcaRows(mean.data(), basis.data(), 2, {{1, 1.0}}, m, b);
  EXPECT_EQ(std::vector<float>(m, m + 3), std::vector<float>({10, 20, 30}));
  EXPECT_EQ(std::vector<float>(b, b + 6), std::vector<float>({1, 2, 3, 4, 5, 6}));
  combinePcaRows(mean.data(), basis.data(), 2, {{0, 0.75}, {1, 0.25}}, m, b);
  EXPECT_FLOAT_EQ(m[0], 0.75f * 1 + 0.25f * 10);
  EXPECT_FLOAT_EQ(m[2], 0.75f * 3 + 0.25f * 30);
  EXPECT_FLOAT_EQ(b[5], 0.75f * 0.6f + 0.25f * 6);
  // The texel value: mean + coefficients . basis row, per channel (C = 9 covers the tail).
  std::vector<float> coefficients(9), rows(27);
  for (int k = 0; k < 9; ++k) coefficients[k] = 0.5f * (k + 1);
  for (int k = 0; k < 27; ++k) rows[k] = 0.1f * (k % 5) - 0.2f;
  const float mean3[3] = {0.25f, -1, 2};
  float rgb[3];
  pcaTexelValue(coefficients.data(), mean3, rows.data(), 9, rgb);
  for (int ch = 0; ch < 3; ++ch) {
    double expected = mean3[ch];
    for (int k = 0; k < 9; ++k) expected += double(coefficients[k]) * rows[ch * 9 + k];
    EXPECT_NEAR(rgb[ch], expected, 1e-5) << ch;
  }
}

}  // namespace
}  // namespace nbtf
