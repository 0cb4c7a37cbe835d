// A fitted material's value (gltf/gltf_material.h) and its 8-bit textures.
#include "gltf/gltf_material.h"

#include <gtest/gtest.h>

#include <cmath>

#include "test_util.h"

namespace nbtf::gltf {
namespace {

GltfMaterial twoTexels() {
  GltfMaterial m;
  m.width = 2, m.height = 1, m.exposure = 3.0;
  m.texels.resize(2);
  m.texels[0].brdf.baseColor = {0.8, 0.4, 0.1};
  m.texels[0].brdf.roughness = 0.6;
  m.texels[1].brdf.baseColor = {0.2, 0.9, 0.5};
  m.texels[1].brdf.metallic = 1;
  m.texels[1].brdf.roughness = 0.3;
  const double s = std::sqrt(0.2 * 0.2 + 0.1 * 0.1 + 1);
  m.texels[1].normal = {0.2 / s, -0.1 / s, 1 / s};
  return m;
}

TEST(GltfMaterial, AValueIsExposureTimesTheBrdfTimesTheShadingCosine) {
  const GltfMaterial m = twoTexels();
  const Vec3 l{0.6, 0, 0.8}, v{0, 0, 1};
  for (int t = 0; t < 2; ++t) {
    const TexelParams& p = m.texels[t];
    const double cosL = p.normal[0] * l[0] + p.normal[1] * l[1] + p.normal[2] * l[2];
    const Vec3 f = evaluateBrdf(p.brdf, p.normal, l, v), got = m.value(t, l, v);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[c], 3.0 * f[c] * cosL, 1e-12);
  }
  // A light behind the shading normal gives nothing, though above the macro surface.
  GltfMaterial tilted = m;
  tilted.texels[0].normal = {0.7071068, 0, 0.7071068};
  EXPECT_EQ(tilted.value(0, {-0.8, 0, 0.6}, v)[0], 0);
}

TEST(GltfMaterial, TexturesHoldEightBitsOfEachParameterAndTheNormalWithGreenUpTheImage) {
  const GltfMaterial m = twoTexels();
  const TextureSet t = quantize(m);
  ASSERT_EQ(t.baseColor.size(), 6u);
  // Roughness in green, metallic in blue (the glTF channel assignment); linear 8-bit.
  EXPECT_EQ(t.metallicRoughness[1], std::lround(0.6 * 255));
  EXPECT_EQ(t.metallicRoughness[2], 0);
  EXPECT_EQ(t.metallicRoughness[5], 255);
  // The BTF frame's y runs down the image (increasing v), glTF's green up: stored -n_y.
  EXPECT_GT(t.normal[3 + 1], 128);
  EXPECT_GT(t.normal[3 + 0], 128);
  const GltfMaterial back = dequantize(t, m.exposure, "test");
  for (int i = 0; i < 2; ++i) {
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(back.texels[i].brdf.baseColor[c], m.texels[i].brdf.baseColor[c], 0.01);
      EXPECT_NEAR(back.texels[i].normal[c], m.texels[i].normal[c], 0.01);
    }
    EXPECT_NEAR(back.texels[i].brdf.roughness, m.texels[i].brdf.roughness, 0.5 / 255 + 1e-9);
    EXPECT_NEAR(back.texels[i].brdf.metallic, m.texels[i].brdf.metallic, 0.5 / 255 + 1e-9);
  }
  // Quantizing what was read back changes nothing: the textures are the material.
  const TextureSet again = quantize(back);
  EXPECT_EQ(again.baseColor, t.baseColor);
  EXPECT_EQ(again.metallicRoughness, t.metallicRoughness);
  EXPECT_EQ(again.normal, t.normal);
}

TEST(GltfMaterial, SheenTravelsInOneRgbaTextureColourInSrgbRoughnessInAlpha) {
  GltfMaterial m = twoTexels();
  m.sheen = true;
  m.texels[0].brdf.sheenColor = {0.2, 0.5, 0.04};
  m.texels[0].brdf.sheenRoughness = 0.7;
  const TextureSet t = quantize(m);
  ASSERT_EQ(t.sheen.size(), 8u);
  EXPECT_EQ(t.sheen[3], std::lround(0.7 * 255));
  const GltfMaterial back = dequantize(t, m.exposure, "test");
  EXPECT_TRUE(back.sheen);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(back.texels[0].brdf.sheenColor[c], m.texels[0].brdf.sheenColor[c], 0.01);
  EXPECT_NEAR(back.texels[0].brdf.sheenRoughness, 0.7, 0.5 / 255 + 1e-9);
  EXPECT_TRUE(quantize(twoTexels()).sheen.empty());  // no sheen, no fourth texture
}

TEST(GltfMaterial, SpecularTravelsAsAGreyTextureScaledByItsFactor) {
  GltfMaterial m = twoTexels();
  m.specular = true;
  m.texels[0].brdf.specularF0 = 0.02;
  m.texels[1].brdf.specularF0 = 0.12;
  const TextureSet t = quantize(m);
  ASSERT_EQ(t.specular.size(), 6u);
  EXPECT_NEAR(t.specularColorFactor, 0.12 / 0.04, 1e-12);  // the largest F0 is the texture's white
  EXPECT_EQ(t.specular[3], 255);
  const GltfMaterial back = dequantize(t, m.exposure, "test");
  EXPECT_TRUE(back.specular);
  EXPECT_NEAR(back.texels[0].brdf.specularF0, 0.02, 2e-4);
  EXPECT_NEAR(back.texels[1].brdf.specularF0, 0.12, 1e-9);
  EXPECT_TRUE(quantize(twoTexels()).specular.empty());
  EXPECT_EQ(dequantize(quantize(twoTexels()), 1, "t").texels[0].brdf.specularF0, kDielectricF0);
}

TEST(GltfMaterial, TexturesOfDifferentSizesAreRefused) {
  TextureSet t = quantize(twoTexels());
  t.normal.resize(3);
  test::expectErrorContaining([&] { dequantize(t, 1, "m.gltf"); }, {"m.gltf", "same size"});
}

}  // namespace
}  // namespace nbtf::gltf
