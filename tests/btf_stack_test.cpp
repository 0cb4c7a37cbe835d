#include "io/btf_stack.h"

#include <gtest/gtest.h>

#include "io/color.h"
#include "util/error.h"

namespace nbtf {

TEST(BtfStack, ShapeAndIndexing) {
  BtfStack s({{0, 0}, {15, 0}}, {{0, 0}, {15, 0}, {15, 60}}, 4, 2, SampleType::Srgb8);
  EXPECT_EQ(s.numImages(), 6);
  EXPECT_EQ(s.numTexels(), 8);
  EXPECT_EQ(s.imageIndex(1, 2), 5);
  EXPECT_EQ(s.bytesInMemory(), 6u * 8 * 3);
  EXPECT_EQ(s.rawFloat32Bytes(), 6u * 8 * 3 * 4);
}

TEST(BtfStack, HalfStorageKeepsLinearValues) {
  BtfStack s({{0, 0}}, {{0, 0}, {30, 0}}, 2, 1, SampleType::Half);
  EXPECT_EQ(s.bytesInMemory(), 2u * 2 * 3 * 2);
  std::vector<float> a = {0.1f, 0.2f, 3.0f, 0.0f, 0.5f, 1.0f}, b = {1, 1, 1, 2, 2, 2};
  s.setImageLinear(0, a.data());
  s.setImageLinear(1, b.data());
  EXPECT_NEAR(s.sample(0, 0, 2), 3.0f, 1e-3);
  auto abrdf = s.abrdfLinear(1);
  ASSERT_EQ(abrdf.size(), 6u);
  EXPECT_NEAR(abrdf[1], 0.5f, 1e-3);
  EXPECT_FLOAT_EQ(abrdf[4], 2.0f);
  float lo, hi;
  s.valueRange(lo, hi);
  EXPECT_FLOAT_EQ(lo, 0);
  EXPECT_FLOAT_EQ(hi, 3);
}

TEST(BtfStack, Srgb8StorageLinearizesOnAccess) {
  BtfStack s({{0, 0}}, {{0, 0}}, 1, 1, SampleType::Srgb8);
  s.imageBytes(0)[0] = 128;
  s.imageBytes(0)[1] = 0;
  s.imageBytes(0)[2] = 255;
  EXPECT_FLOAT_EQ(s.sample(0, 0, 0), srgb8ToLinear(128));
  float img[3];
  s.imageLinear(0, img);
  EXPECT_FLOAT_EQ(img[2], 1.0f);
}

// 2 x 2 images of 3 x 2 texels whose values rise by `step`, image after image.
static BtfStack rampStack(SampleType type, float step) {
  BtfStack s({{0, 0}, {15, 0}}, {{0, 0}, {30, 0}}, 3, 2, type);
  std::vector<float> rgb(6 * 3);
  for (int i = 0; i < 4; ++i) {
    for (std::size_t v = 0; v < rgb.size(); ++v) rgb[v] = step * static_cast<float>(i * 18 + v);
    s.setImageLinear(i, rgb.data());
  }
  return s;
}

// gatherLinear: any texels in any images, dimension-major, the values sample() gives.
TEST(BtfStack, GatherLinearReadsTexelsInImages) {
  for (SampleType type : {SampleType::Srgb8, SampleType::Half}) {
    const BtfStack s = rampStack(type, 0.01f);
    const std::vector<int> images = {3, 1}, texels = {5, 0, 2};
    std::vector<float> out(2 * 3 * 3, -1.0f);
    s.gatherLinear(images.data(), 2, texels.data(), 3, out.data());
    for (int j = 0; j < 2; ++j)
      for (int c = 0; c < 3; ++c)
        for (int k = 0; k < 3; ++k) EXPECT_EQ(out[(3 * j + c) * 3 + k], s.sample(images[j], texels[k], c));
    std::vector<float> all(4 * 3);
    const int texel = 4;
    s.gatherLinear(nullptr, 0, &texel, 1, all.data());  // every image: one texel's ABRDF
    EXPECT_EQ(all, s.abrdfLinear(texel));
    EXPECT_FALSE(s.isComputed());
  }
}

// gatherStored: gatherLinear's values as stored (1 byte for 8-bit, 2 for half), which
// storedToLinear turns into gatherLinear's floats times a scale, bit for bit.
TEST(BtfStack, GatherStoredGivesGatherLinearsValuesAfterConversion) {
  for (SampleType type : {SampleType::Srgb8, SampleType::Half}) {
    const BtfStack s = rampStack(type, 0.013f);
    EXPECT_EQ(s.storedValueBytes(), type == SampleType::Srgb8 ? 1u : 2u);
    const std::vector<int> images = {3, 1, 2}, texels = {5, 0, 2, 4};
    const std::size_t n = 3 * images.size() * texels.size();
    std::vector<float> linear(n);
    s.gatherLinear(images.data(), 3, texels.data(), 4, linear.data());
    std::vector<std::uint8_t> stored(n * s.storedValueBytes());
    s.gatherStored(images.data(), 3, texels.data(), 4, stored.data());
    for (float scale : {1.0f, 1.0f / 0.83f}) {
      std::vector<float> converted(n);
      s.storedToLinear(stored.data(), n, scale, converted.data());
      for (std::size_t v = 0; v < n; ++v) EXPECT_EQ(converted[v], linear[v] * scale) << "value " << v;
    }
    // Part of a run converts alone: the second image's values.
    std::vector<float> part(12);
    s.storedToLinear(stored.data() + 12 * s.storedValueBytes(), 12, 1.0f, part.data());
    EXPECT_EQ(part, std::vector<float>(linear.begin() + 12, linear.begin() + 24));
  }
}

}  // namespace nbtf
