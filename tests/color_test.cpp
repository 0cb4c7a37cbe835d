#include "io/color.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

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

TEST(Color, FastSrgb8EncoderIsExact) {
  Srgb8Encoder encode;
  auto check = [&](float x) { ASSERT_EQ(int(encode(x)), int(linearToSrgb8(x))) << x; };
  std::uint32_t one;
  const float f1 = 1.0f;
  std::memcpy(&one, &f1, 4);
  for (std::uint32_t bits = 0; bits <= one; bits += 251) {  // every table bucket, many times
    float x;
    std::memcpy(&x, &bits, 4);
    check(x);
  }
  // Around every rounding threshold.
  for (int code = 0; code < 255; ++code) {
    float t = srgb8ToLinear(static_cast<std::uint8_t>(code));
    float mid = 0.5f * (t + srgb8ToLinear(static_cast<std::uint8_t>(code + 1)));
    for (float x = mid, n = 0; n < 40; ++n) x = std::nextafter(x, 0.0f), check(x);
    for (float x = mid, n = 0; n < 40; ++n) x = std::nextafter(x, 2.0f), check(x);
  }
  for (float x : {-1.0f, -0.0f, 1.5f, 1e30f, INFINITY, NAN}) check(x);
}

}  // namespace nbtf
