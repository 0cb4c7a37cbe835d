// Material sources (render/material_source.h): the direction interpolation of a stack, a stack at
// measured directions, a .nbtf rendered through the decoder against a render of its own decoded
// stack, and the errors for a missing material or an unknown scene.
#include <gtest/gtest.h>

#include <cmath>

#include "codec/decoder.h"
#include "pipeline/decoder_output.h"
#include "decoder_fixtures.h"
#include "render/compare.h"
#include "render/integrator.h"
#include "render/material_source.h"
#include "render/scene.h"
#include "test_util.h"
#include "util/atomic_file.h"

namespace nbtf {
namespace {

std::array<float, 3> unitOf(const Direction& d) {
  auto u = d.unitVector();
  return {static_cast<float>(u[0]), static_cast<float>(u[1]), static_cast<float>(u[2])};
}

TEST(RenderMaterial, InterpolatorPicksMeasuredDirectionsExactly) {
  const DirectionInterpolator interp(hemisphere81(), 3);
  for (int i : {0, 7, 40, 80}) {
    const DirectionWeights w = interp.weights(unitOf(hemisphere81()[i]));
    ASSERT_EQ(w.count, 1);
    EXPECT_EQ(w.index[0], i);
    EXPECT_EQ(w.weight[0], 1.0f);
  }
  const DirectionWeights w = interp.weights(unitOf({37.5, 200}));
  ASSERT_EQ(w.count, 3);
  EXPECT_NEAR(w.weight[0] + w.weight[1] + w.weight[2], 1.0, 1e-6);
  EXPECT_GE(w.weight[0], w.weight[1]);  // nearest first, heaviest
  EXPECT_GE(w.weight[1], w.weight[2]);
  EXPECT_EQ(w.index[0], nearestDirection(hemisphere81(), {37.5, 200}));
}

TEST(RenderMaterial, StackAtMeasuredDirectionsIsTheMeasuredValue) {
  BtfStack stack(hemisphere81(), hemisphere81(), 3, 2, SampleType::Half);
  std::vector<float> img(3 * 3 * 2);
  for (int i = 0; i < stack.numImages(); ++i) {
    for (std::size_t k = 0; k < img.size(); ++k) img[k] = 0.01f * static_cast<float>((i * 7 + k * 3) % 50);
    stack.setImageLinear(i, img.data());
  }
  const StackMaterial m(stack, "mem");
  UvQuery q;
  q.u = (2 + 0.5f) / 3, q.v = (1 + 0.5f) / 2 + 3;  // texel (2, 1), tiled
  q.light = unitOf(hemisphere81()[12]);
  q.view = unitOf(hemisphere81()[30]);
  float rgb[3];
  m.evaluate(&q, 1, rgb);
  const int texel = 1 * 3 + 2, image = stack.imageIndex(12, 30);
  for (int c = 0; c < 3; ++c) EXPECT_FLOAT_EQ(rgb[c], stack.sample(image, texel, c));
}

TEST(RenderMaterial, NbtfAgreesWithItsOwnDecodedStack) {
  const CompressedBtf b = testing::makeSmoothMaterial(3, 6, 4);
  const NbtfMaterial compressed(NbtfDecoder(b, {}, "smooth.nbtf"));
  const StackMaterial decoded(decodeStack(compressed.decoder(), SampleType::Half, {}, {}, false), "decoded");
  Scene scene = makeScene("sphere", 2);
  RenderOptions o;
  o.width = 64, o.height = 48, o.mode = SamplingMode::Uniform, o.uniform = 2, o.progress = false;
  const Camera cam(scene.camera, o.width, o.height);
  const RenderResult a = renderImage(scene, cam, compressed, o);
  const RenderResult s = renderImage(scene, cam, decoded, o);
  const RenderComparison c = compareImages(a.rgb, s.rgb, a.coverage, o.width, o.height);
  // The material's own signal on the sphere, for scale.
  double mean = 0, var = 0;
  std::size_t n = 0;
  for (std::size_t p = 0; p < a.coverage.size(); ++p)
    if (a.coverage[p] == 1.0f) mean += a.rgb[3 * p], ++n;
  ASSERT_GT(n, 300u);
  mean /= n;
  for (std::size_t p = 0; p < a.coverage.size(); ++p)
    if (a.coverage[p] == 1.0f) var += (a.rgb[3 * p] - mean) * (a.rgb[3 * p] - mean);
  const double sd = std::sqrt(var / n);
  ASSERT_GT(sd, 0.02);
  EXPECT_LT(c.all.rmse, 0.1 * sd) << "rmse " << c.all.rmse << " vs the image's spread " << sd;
  EXPECT_LT(c.bright.rmse, 0.03 * mean + 0.1 * sd);
}

TEST(RenderMaterial, NbtfMaterialEqualsTheDecoder) {
  const CompressedBtf b = testing::makeDisplayableMaterial(4, 7, 5);
  NbtfDecoder dec(b);
  const Rgb expect = dec.evaluateUv(0.3f, 0.7f, {30, 60}, {15, 120});
  const NbtfMaterial m(std::move(dec));
  UvQuery q;
  q.u = 0.3f, q.v = 0.7f;
  q.light = unitOf({30, 60});
  q.view = unitOf({15, 120});
  float rgb[3];
  m.evaluate(&q, 1, rgb);
  EXPECT_NEAR(rgb[0], expect.r, 1e-5);
  EXPECT_NEAR(rgb[1], expect.g, 1e-5);
  EXPECT_NEAR(rgb[2], expect.b, 1e-5);
}

TEST(RenderMaterial, MissingMaterialAndUnknownSceneAreClearErrors) {
  test::TempDir dir;
  test::expectErrorContaining([&] { openMaterial(dir / "nope.nbtf"); }, {"nope.nbtf", "no such file"});
  const std::string junk = dir / "junk.nbtf";
  writeFileAtomic(junk, std::string("not a material"));
  test::expectErrorContaining([&] { openMaterial(junk); }, {"junk.nbtf", "not a .nbtf file"});
  test::expectErrorContaining([&] { makeScene("teapot", 1); }, {"--scene", "teapot", "sphere", "cloth"});
  test::expectErrorContaining([&] { parseCamera("1,2", {}, "--camera"); }, {"--camera", "3, 6 or 7"});
}

}  // namespace
}  // namespace nbtf
