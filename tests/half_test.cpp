#include "util/half.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace nbtf {
namespace {

TEST(Half, ExactValuesRoundTrip) {
  for (float v : {0.0f, -0.0f, 1.0f, -2.5f, 0.099975586f, 65504.0f, 6.1035156e-05f /* smallest normal */,
                  5.9604645e-08f /* smallest subnormal */})
    EXPECT_EQ(halfToFloat(floatToHalf(v)), v) << v;
  EXPECT_EQ(floatToHalf(1.0f), 0x3C00);
  EXPECT_EQ(floatToHalf(-2.0f), 0xC000);
  EXPECT_EQ(floatToHalf(65504.0f), 0x7BFF);
}

TEST(Half, RoundsToNearestEven) {
  // 1 + 2^-11 is halfway between 1 and 1 + 2^-10: ties go to the even mantissa (1).
  EXPECT_EQ(floatToHalf(1.0f + std::ldexp(1.0f, -11)), 0x3C00);
  // 1 + 3 x 2^-11 is halfway between 1 + 2^-10 (odd) and 1 + 2^-9 (even).
  EXPECT_EQ(floatToHalf(1.0f + 3 * std::ldexp(1.0f, -11)), 0x3C02);
  EXPECT_EQ(floatToHalf(1.0f + std::ldexp(1.0f, -11) + std::ldexp(1.0f, -20)), 0x3C01);  // above halfway
  // Rounding up may carry into the exponent.
  EXPECT_EQ(halfToFloat(floatToHalf(2047.9f)), 2048.0f);
}

TEST(Half, RelativeErrorIsWithinHalfAnUlp) {
  for (float v = 1e-3f; v < 6e4f; v *= 1.0137f) {
    float r = roundToHalf(v);
    EXPECT_LE(std::fabs(r - v) / v, std::ldexp(1.0, -11) * 1.0001) << v;
  }
}

TEST(Half, OverflowSubnormalsAndSpecials) {
  EXPECT_TRUE(std::isinf(halfToFloat(floatToHalf(1e6f))));
  EXPECT_TRUE(std::isinf(halfToFloat(floatToHalf(-std::numeric_limits<float>::infinity()))));
  EXPECT_TRUE(std::isnan(halfToFloat(floatToHalf(std::numeric_limits<float>::quiet_NaN()))));
  EXPECT_EQ(halfToFloat(floatToHalf(1e-9f)), 0.0f);
  float sub = 3 * 5.9604645e-08f;  // three subnormal steps
  EXPECT_EQ(halfToFloat(floatToHalf(sub)), sub);
  EXPECT_EQ(floatToHalf(sub), 3);
}

}  // namespace
}  // namespace nbtf
