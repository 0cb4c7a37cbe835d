// Drawing helpers: colour map, axis ticks, text placement, display scaling.
#include "eval/canvas.h"

#include <gtest/gtest.h>

namespace nbtf {
namespace {

TEST(Canvas, ViridisEndsAndIsMonotoneInLightness) {
  Color8 lo = viridis(0), hi = viridis(1);
  // matplotlib's viridis: #440154 at 0, #fde725 at 1 (OpenCV's table within a few codes).
  EXPECT_NEAR(lo.r, 0x44, 4);
  EXPECT_NEAR(lo.g, 0x01, 4);
  EXPECT_NEAR(lo.b, 0x54, 4);
  EXPECT_NEAR(hi.r, 0xfd, 4);
  EXPECT_NEAR(hi.g, 0xe7, 4);
  EXPECT_NEAR(hi.b, 0x25, 6);
  double last = -1;
  for (int i = 0; i <= 10; ++i) {
    Color8 c = viridis(i / 10.0);
    double luma = 0.2126 * c.r + 0.7152 * c.g + 0.0722 * c.b;
    EXPECT_GT(luma, last);
    last = luma;
  }
  EXPECT_EQ(viridis(-3).r, lo.r);
  EXPECT_EQ(viridis(7).g, hi.g);
}

TEST(Canvas, NiceTicksAreRoundAndCoverTheRange) {
  auto t = niceTicks(0, 0.1011, 6);
  ASSERT_EQ(t.size(), 6u);
  EXPECT_DOUBLE_EQ(t[0], 0.0);
  EXPECT_NEAR(t[1], 0.02, 1e-12);
  EXPECT_NEAR(t.back(), 0.1, 1e-12);
  auto u = niceTicks(0, 75, 8);
  EXPECT_EQ(u.size(), 8u);  // 0, 10, ..., 70
  EXPECT_NEAR(u[1], 10, 1e-12);
  auto v = niceTicks(0.013, 0.0481, 4);  // 0.02, 0.03, 0.04
  ASSERT_EQ(v.size(), 3u);
  EXPECT_NEAR(v[0], 0.02, 1e-12);
  EXPECT_NEAR(v[2], 0.04, 1e-12);
  EXPECT_EQ(formatTick(0.02, 0.02), "0.02");
  EXPECT_EQ(formatTick(0.005, 0.005), "0.005");
  EXPECT_EQ(formatTick(20, 10), "20");
  EXPECT_EQ(niceTicks(3, 3, 5).size(), 1u);
}

TEST(Canvas, TextIsDrawnWhereAsked) {
  Canvas c(200, 60);
  c.text("RMSE 45\xC2\xB0", 100, 30, 12, kBlack, Align::Center);
  int inkLeft = 200, inkRight = -1, inkTop = 60, inkBottom = -1;
  const auto& img = c.image();
  for (int y = 0; y < 60; ++y)
    for (int x = 0; x < 200; ++x)
      if (img.rgb[(y * 200 + x) * 3] < 128)
        inkLeft = std::min(inkLeft, x), inkRight = std::max(inkRight, x), inkTop = std::min(inkTop, y),
        inkBottom = std::max(inkBottom, y);
  ASSERT_GE(inkRight, 0) << "no ink";
  EXPECT_NEAR((inkLeft + inkRight) / 2.0, 100, 4);
  EXPECT_NEAR((inkTop + inkBottom) / 2.0, 30, 4);
  EXPECT_NEAR(inkBottom - inkTop, 12, 4);
  // The advance width includes side bearings and the degree sign's spacing.
  EXPECT_NEAR(inkRight - inkLeft, c.textWidth("RMSE 45\xC2\xB0", 12), 6);
}

TEST(Canvas, VerticalTextReadsBottomToTop) {
  Canvas c(60, 200);
  c.text("light direction", 30, 100, 12, kBlack, Align::Center, true);
  int top = 200, bottom = -1, left = 60, right = -1;
  const auto& img = c.image();
  for (int y = 0; y < 200; ++y)
    for (int x = 0; x < 60; ++x)
      if (img.rgb[(y * 60 + x) * 3] < 128)
        top = std::min(top, y), bottom = std::max(bottom, y), left = std::min(left, x), right = std::max(right, x);
  EXPECT_GT(bottom - top, 3 * (right - left)) << "taller than wide";
  EXPECT_NEAR((top + bottom) / 2.0, 100, 5);
}

TEST(Canvas, DisplayScaleEnlargesSmallAndShrinksLargeImages) {
  Image8 small;
  small.width = 4, small.height = 2;
  small.rgb.assign(4 * 2 * 3, 0);
  small.rgb[0] = 255;  // top-left texel red
  Image8 big = displayScale(small, 100, 300);
  EXPECT_EQ(big.width, 100);  // factor 25
  EXPECT_EQ(big.height, 50);
  EXPECT_EQ(big.rgb[(24 * 100 + 24) * 3], 255);  // still inside the first texel
  EXPECT_EQ(big.rgb[(24 * 100 + 25) * 3], 0);
  Image8 huge;
  huge.width = 1000, huge.height = 500;
  huge.rgb.assign(1000 * 500 * 3, 90);
  Image8 fit = displayScale(huge, 100, 400);
  EXPECT_EQ(fit.width, 400);
  EXPECT_EQ(fit.height, 200);
  EXPECT_EQ(fit.rgb[123], 90);
}

}  // namespace
}  // namespace nbtf
