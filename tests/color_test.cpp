#include "io/color.h"

#include <gtest/gtest.h>

namespace nbtf {

TEST(Color, SrgbCurveKnownValues) {
  EXPECT_FLOAT_EQ(srgb8ToLinear(0), 0.0f);
  EXPECT_FLOAT_EQ(srgb8ToLinear(255), 1.0f);
  EXPECT_NEAR(srgb8ToLinear(128), 0.2158605f, 1e-6);  // ((128/255 + 0.055) / 1.055)^2.4
  EXPECT_NEAR(srgb8ToLinear(10), 10 / 255.0f / 12.92f, 1e-7);  // linear toe
}

TEST(Color, EightBitRoundTripIsExact) {
  for (int v = 0; v < 256; ++v) EXPECT_EQ(linearToSrgb8(srgb8ToLinear(static_cast<std::uint8_t>(v))), v);
  EXPECT_EQ(linearToSrgb8(-1.0f), 0);
  EXPECT_EQ(linearToSrgb8(7.0f), 255);
}

TEST(Color, XyzRoundTripAndWhitePoint) {
  float white[3] = {1, 1, 1};
  linearSrgbToXyz(white);
  EXPECT_NEAR(white[0], 0.95047f, 1e-4);  // D65
  EXPECT_NEAR(white[1], 1.0f, 1e-4);
  EXPECT_NEAR(white[2], 1.08883f, 1e-4);
  float c[3] = {0.2f, 0.5f, 0.9f};
  linearSrgbToXyz(c);
  xyzToLinearSrgb(c);
  EXPECT_NEAR(c[0], 0.2f, 1e-5);
  EXPECT_NEAR(c[1], 0.5f, 1e-5);
  EXPECT_NEAR(c[2], 0.9f, 1e-5);
}

}  // namespace nbtf
