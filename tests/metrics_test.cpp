// Error metrics against hand-computed values (python, see comments), and the per-image
// table's groupings (pooled, not averaged).
#include "eval/metrics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "test_util.h"
#include "util/error.h"

namespace nbtf {
namespace {

// reference / reconstruction, linear, alpha = 2: normalized differences 0, -1/8, 1/8, 0, 1/8, 0.
const float kRef[6] = {0.5f, 0.25f, 1.0f, 0.0f, 0.5f, 0.5f};
const float kRec[6] = {0.5f, 0.5f, 0.75f, 0.0f, 0.25f, 0.5f};

TEST(Metrics, RmseIsEq10OnAlphaNormalizedValues) {
  // sqrt(3 * (1/8)^2 / 6) = sqrt(1/128)
  EXPECT_NEAR(rmseLinear(kRef, kRec, 6, 2.0f), 0.08838834764831845, 1e-12);
  // alpha scales the error: alpha = 1 doubles it.
  EXPECT_NEAR(rmseLinear(kRef, kRec, 6, 1.0f), 2 * 0.08838834764831845, 1e-12);
}

TEST(Metrics, Srgb8RmseUsesCodeUnits) {
  // sRGB8 codes: 0.5 -> 188, 0.25 -> 137, 1.0 -> 255, 0.75 -> 225, 0 -> 0.
  // Squared code differences 0, 51^2, 30^2, 0, 51^2, 0 -> sqrt(6102 / 6) = 31.8904...
  EXPECT_NEAR(rmseSrgb8(kRef, kRec, 6), 31.89043743820395, 1e-9);
}

TEST(Metrics, PsnrHasStatedPeaks) {
  ErrorSummary s = summarize(errorSums(kRef, kRec, 6, 2.0f));
  EXPECT_EQ(s.count, 6u);
  EXPECT_NEAR(s.psnr, 21.072099696478684, 1e-9);        // 20 log10(1 / 0.0883883)
  EXPECT_NEAR(s.psnrSrgb8, 18.057594079451658, 1e-9);   // 20 log10(255 / 31.8904)
  EXPECT_NEAR(psnrFromRmse(0.1, 1.0), 20.0, 1e-12);
  EXPECT_TRUE(std::isinf(psnrFromRmse(0.0, 1.0)));
}

TEST(Metrics, IdenticalImagesHaveZeroErrorAndInfinitePsnr) {
  ErrorSummary s = summarize(errorSums(kRef, kRef, 6, 1.0f));
  EXPECT_EQ(s.rmse, 0.0);
  EXPECT_EQ(s.rmseSrgb8, 0.0);
  EXPECT_TRUE(std::isinf(s.psnr) && s.psnr > 0);
}

TEST(Metrics, NonFiniteValuesAreRejectedWithTheirPosition) {
  float bad[6] = {0.5f, 0.25f, 1.0f, 0.0f, std::numeric_limits<float>::quiet_NaN(), 0.5f};
  test::expectErrorContaining([&] { errorSums(kRef, bad, 6, 1.0f); }, {"reconstruction", "texel 1", "channel 1"});
  bad[4] = std::numeric_limits<float>::infinity();
  test::expectErrorContaining([&] { errorSums(bad, kRec, 6, 1.0f); }, {"reference", "not finite"});
  test::expectErrorContaining([&] { errorSums(kRef, kRec, 6, 0.0f); }, {"alpha"});
}

// 2 lights (theta 0 and 30) x 3 views (theta 0, 45, 45): image = light * 3 + view.
ErrorTable smallTable() {
  ErrorTable t({{0, 0}, {30, 90}}, {{0, 0}, {45, 0}, {45, 180}});
  for (int i = 0; i < 6; ++i) {
    ErrorSums s;
    s.squaredLinear = i + 1;        // 1, 2, ..., 6
    s.squaredSrgb8 = 100.0 * (i + 1);
    s.count = 10;
    t.set(i, s);
  }
  return t;
}

TEST(Metrics, TablePoolsSquaredErrorsOverGroups) {
  ErrorTable t = smallTable();
  EXPECT_NEAR(t.all().rmse, std::sqrt(21.0 / 60), 1e-12);
  EXPECT_NEAR(t.all().rmseSrgb8, std::sqrt(2100.0 / 60), 1e-12);
  EXPECT_NEAR(t.image(4).rmse, std::sqrt(5.0 / 10), 1e-12);
  // Hold-out images 1 and 5: (2 + 6) / 20; training: (1 + 3 + 4 + 5) / 40.
  EXPECT_NEAR(t.subset({5, 1}, false).rmse, std::sqrt(8.0 / 20), 1e-12);
  EXPECT_NEAR(t.subset({5, 1}, true).rmse, std::sqrt(13.0 / 40), 1e-12);
  EXPECT_EQ(t.worstImage(), 5);
  auto map = t.rmseMap();
  ASSERT_EQ(map.size(), 6u);
  EXPECT_NEAR(map[2], std::sqrt(3.0 / 10), 1e-12);
}

TEST(Metrics, TableGroupsByLightAndViewElevation) {
  ErrorTable t = smallTable();
  auto byLight = t.byLightElevation();
  ASSERT_EQ(byLight.size(), 2u);
  EXPECT_EQ(byLight[0].thetaDeg, 0);
  EXPECT_EQ(byLight[0].directions, 1);
  EXPECT_EQ(byLight[0].images, 3);
  EXPECT_NEAR(byLight[0].error.rmse, std::sqrt(6.0 / 30), 1e-12);   // images 0, 1, 2
  EXPECT_NEAR(byLight[1].error.rmse, std::sqrt(15.0 / 30), 1e-12);  // images 3, 4, 5
  auto byView = t.byViewElevation();
  ASSERT_EQ(byView.size(), 2u);
  EXPECT_EQ(byView[1].thetaDeg, 45);
  EXPECT_EQ(byView[1].directions, 2);
  EXPECT_EQ(byView[1].images, 4);
  // Pooled over images 1, 2, 4, 5: sqrt((2 + 3 + 5 + 6) / 40), not the mean of four RMSEs.
  EXPECT_NEAR(byView[1].error.rmse, std::sqrt(16.0 / 40), 1e-12);
}

TEST(Metrics, HoldoutListsAreValidated) {
  EXPECT_NO_THROW(checkHoldoutImages({0, 5}, 6));
  test::expectErrorContaining([] { checkHoldoutImages({0, 6}, 6); }, {"entry 1", "6", "0..5"});
  test::expectErrorContaining([] { checkHoldoutImages({2, 2}, 6); }, {"image 2", "twice"});
  ErrorTable t = smallTable();
  EXPECT_THROW(t.subset({-1}, false), Error);
}

}  // namespace
}  // namespace nbtf
