#include "util/half.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

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

std::uint32_t bitsOf(float v) {
  std::uint32_t b;
  std::memcpy(&b, &v, 4);
  return b;
}
float floatOf(std::uint32_t b) {
  float v;
  std::memcpy(&v, &b, 4);
  return v;
}

// roundToHalf (branch-free) against the two conversions, bit for bit: at and around every
// half and every midpoint between neighbouring halves (where rounding decides), both signs,
// and a sample of all floats.
TEST(Half, RoundToHalfIsTheConversionsBitForBit) {
  auto expectSame = [](std::uint32_t b) {
    const float v = floatOf(b);
    ASSERT_EQ(bitsOf(roundToHalf(v)), bitsOf(halfToFloat(floatToHalf(v)))) << std::hex << b;
  };
  int checked = 0;
  for (std::uint32_t h = 0; h < 0x7C00u; ++h) {  // finite positive halves and the next one up
    const float lo = halfToFloat(static_cast<std::uint16_t>(h)), hi = halfToFloat(static_cast<std::uint16_t>(h + 1));
    for (std::uint32_t centre : {bitsOf(lo), bitsOf((lo + hi) / 2)})  // (lo + hi) / 2 is exact
      for (std::uint32_t b = centre - 2; b != centre + 3; ++b)
        for (std::uint32_t sign : {0u, 0x80000000u}) expectSame((b & 0x7FFFFFFFu) | sign), ++checked;
  }
  for (std::uint64_t b = 0; b <= 0xFFFFFFFFull; b += 9973) expectSame(static_cast<std::uint32_t>(b)), ++checked;
  for (std::uint32_t b : {0x7F800000u, 0xFF800000u, 0x7FC00000u, 0x7F800001u, 0xFFFFFFFFu}) expectSame(b), ++checked;
  EXPECT_GT(checked, 1000000);
}

}  // namespace
TEST(Half, RoundToHalfClampedAtZeroIsTheScalarFormBitForBit) {
  // Every 997th float bit pattern (both signs, subnormals, infinities, NaNs), in arrays whose
  // length is not a multiple of 4, so the scalar tail runs too.
  std::vector<float> values, expected;
  for (std::uint64_t b = 0; b <= 0xFFFFFFFFull; b += 997) {
    const float v = floatOf(static_cast<std::uint32_t>(b));
    values.push_back(v);
    expected.push_back(roundToHalf(std::max(0.0f, v)));
  }
  for (std::uint32_t b : {0x7F800000u, 0xFF800000u, 0x7FC00000u, 0x80000000u, 0x477FEFFFu, 0x477FF000u, 0x387FFFFFu}) {
    values.push_back(floatOf(b));
    expected.push_back(roundToHalf(std::max(0.0f, floatOf(b))));
  }
  if (values.size() % 4 == 0) values.push_back(1.0f), expected.push_back(1.0f);
  roundToHalfClampedAtZero(values.data(), values.size());
  ASSERT_EQ(values.size(), expected.size());
  std::size_t differing = 0;
  for (std::size_t i = 0; i < values.size(); ++i) differing += bitsOf(values[i]) != bitsOf(expected[i]);
  EXPECT_EQ(differing, 0u);
  EXPECT_GT(values.size(), 4000000u);
}

}  // namespace nbtf
