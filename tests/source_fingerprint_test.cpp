#include "io/source_fingerprint.h"

#include <gtest/gtest.h>

#include "model_test_material.h"
#include "test_util.h"

namespace nbtf {
namespace {

// The model tests' material (half float) and the same values stored as 8-bit sRGB.
BtfStack asSrgb8(const BtfStack& s) {
  BtfStack out(s.lights(), s.views(), s.width(), s.height(), SampleType::Srgb8);
  std::vector<float> rgb(static_cast<std::size_t>(s.numTexels()) * 3);
  for (int i = 0; i < s.numImages(); ++i) {
    s.imageLinear(i, rgb.data());
    out.setImageLinear(i, rgb.data());
  }
  return out;
}

BtfStack scaled(const BtfStack& s, float r, float g, float b) {
  BtfStack out(s.lights(), s.views(), s.width(), s.height(), s.sampleType());
  std::vector<float> rgb(static_cast<std::size_t>(s.numTexels()) * 3);
  const float f[3] = {r, g, b};
  for (int i = 0; i < s.numImages(); ++i) {
    s.imageLinear(i, rgb.data());
    for (std::size_t j = 0; j < rgb.size(); ++j) rgb[j] *= f[j % 3];
    out.setImageLinear(i, rgb.data());
  }
  return out;
}

TEST(SourceFingerprint, EvenlySpacedImagesAndExactMeans) {
  const BtfStack& s = testing::makeTestMaterial().stack;  // 81 images, 8 x 8 texels
  SourceFingerprint fp = sourceFingerprint(s, 32);
  ASSERT_EQ(fp.images.size(), 32u);
  EXPECT_EQ(fp.images.front(), 0);
  EXPECT_EQ(fp.images[1], 2);  // 81 / 32 = 2.53
  EXPECT_LT(fp.images.back(), 81);
  std::vector<float> rgb(static_cast<std::size_t>(s.numTexels()) * 3);
  s.imageLinear(fp.images[5], rgb.data());
  double g = 0;
  for (int t = 0; t < s.numTexels(); ++t) g += rgb[t * 3 + 1];
  EXPECT_NEAR(fp.meanRgb[5][1], g / s.numTexels(), 1e-9);
  EXPECT_EQ(sourceFingerprint(s, 500).images.size(), 81u);
}

TEST(SourceFingerprint, SameMaterialMatchesAlsoAs8BitOtherMaterialDoesNot) {
  const BtfStack& s = testing::makeTestMaterial().stack;
  SourceFingerprint fp = sourceFingerprint(s);
  FingerprintCheck same = checkSourceFingerprint(fp, s);
  EXPECT_TRUE(same.matches);
  EXPECT_EQ(same.medianDifference, 0);
  FingerprintCheck eight = checkSourceFingerprint(fp, asSrgb8(s));
  EXPECT_TRUE(eight.matches) << eight.medianDifference << " pattern " << eight.patternDifference;
  EXPECT_LT(eight.medianDifference, 0.02);
  FingerprintCheck other = checkSourceFingerprint(fp, scaled(s, 0.5f, 1.0f, 1.6f));
  EXPECT_FALSE(other.matches);
  EXPECT_GT(other.medianDifference, 0.3);
  EXPECT_GE(other.worstImage, 0);
}

TEST(SourceFingerprint, JsonRoundTripAbsentAndMalformed) {
  const BtfStack& s = testing::makeTestMaterial().stack;
  SourceFingerprint fp = sourceFingerprint(s, 4);
  std::string meta = R"({"seed": 1, "source": {"layout": "utia", "fingerprint": )" + sourceFingerprintJson(fp) + "}}";
  std::optional<SourceFingerprint> back = sourceFingerprintOf(meta, "m.nbtf");
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(back->images, fp.images);
  EXPECT_EQ(back->meanRgb, fp.meanRgb);
  EXPECT_FALSE(sourceFingerprintOf(R"({"source": {"layout": "utia"}})", "m.nbtf").has_value());
  EXPECT_FALSE(sourceFingerprintOf("{}", "m.nbtf").has_value());
  test::expectErrorContaining(
      [] { sourceFingerprintOf(R"({"source": {"fingerprint": {"images": [1], "mean_linear_rgb": [[1, 2]]}}})", "m.nbtf"); },
      {"m.nbtf", "malformed source fingerprint", "RGB triple"});
}

}  // namespace
}  // namespace nbtf
