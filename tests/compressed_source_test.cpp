// A .nbtf material as the evaluation's reconstruction: decoded images equal a plain per-texel
// decoder evaluation, and a reference that is not the file's material is rejected, naming
// what differs.
#include "eval/compressed_source.h"

#include <gtest/gtest.h>

#include <cmath>

#include "pipeline/compressor.h"
#include "codec_fixtures.h"
#include "model_test_material.h"
#include "test_util.h"
#include "util/progress.h"

namespace nbtf {
namespace {

// The decoder evaluated the plain way for one texel (independent of Mlp::forward).
std::array<float, 3> decodeTexel(const CompressedBtf& b, int light, int view, int texel) {
  std::vector<double> x(b.latentOfTexel(texel), b.latentOfTexel(texel) + b.latentDim);
  float d[kMaxDirectionInputs];
  encodeDirections(b.directionEncoding, b.lights[light], b.views[view], d);
  x.insert(x.end(), d, d + directionInputCount(b.directionEncoding));
  for (const auto& layer : b.decoder.layers) {
    std::vector<double> y(layer.out);
    for (int o = 0; o < layer.out; ++o) {
      double s = layer.bias[o];
      for (int i = 0; i < layer.in; ++i) s += layer.weight[static_cast<std::size_t>(o) * layer.in + i] * x[i];
      if (layer.activation == Activation::Relu) s = std::max(0.0, s);
      if (layer.activation == Activation::Sigmoid) s = 1 / (1 + std::exp(-s));
      y[o] = s;
    }
    x = y;
  }
  return {float(x[0] * b.alpha), float(x[1] * b.alpha), float(x[2] * b.alpha)};
}

class CompressedSource : public ::testing::TestWithParam<int> {};

TEST_P(CompressedSource, ImagesAreTheDecoderOutputTimesAlphaScatteredById) {
  CompressedBtf b = testing::makeBtf(GetParam(), 5, 4);
  CompressedReconstruction rec(b);
  EXPECT_EQ(rec.evaluationsPerImage(), GetParam() > 0 ? GetParam() : 20);
  std::vector<float> img(static_cast<std::size_t>(b.numTexels()) * 3);
  for (int image = 0; image < b.numImages(); ++image) {
    rec.image(image, img.data());
    int light = image / static_cast<int>(b.views.size()), view = image % static_cast<int>(b.views.size());
    for (int t = 0; t < b.numTexels(); ++t) {
      auto want = decodeTexel(b, light, view, t);
      for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(img[3 * t + c], want[c], 1e-4 * (1 + std::abs(want[c]))) << image << " " << t << " " << c;
    }
  }
}
INSTANTIATE_TEST_SUITE_P(ClusteredAndPerTexel, CompressedSource, ::testing::Values(3, 0));

BtfStack matchingStack(const CompressedBtf& b) {
  return BtfStack(b.lights, b.views, b.width, b.height, SampleType::Half);
}

TEST(CompressedSourceCheck, AcceptsTheMaterialAndNamesWhatDiffers) {
  CompressedBtf b = testing::makeBtf(3, 4, 3);
  EXPECT_NO_THROW(checkReferenceMatches(b, matchingStack(b), "m.nbtf", "ref"));

  BtfStack small(b.lights, b.views, 4, 2, SampleType::Half);
  test::expectErrorContaining([&] { checkReferenceMatches(b, small, "m.nbtf", "ref"); },
                              {"'ref' does not match 'm.nbtf'", "texel size", "4 x 2 in the reference",
                               "4 x 3 in the file", "crop 3,5,4,3"});
  auto lights = b.lights;
  lights[2] = {15, 120};
  BtfStack otherLight(lights, b.views, 4, 3, SampleType::Half);
  test::expectErrorContaining([&] { checkReferenceMatches(b, otherLight, "m.nbtf", "ref"); },
                              {"light direction 2", "(15\xC2\xB0, 120\xC2\xB0) in the reference",
                               "(15\xC2\xB0, 60\xC2\xB0) in the file"});
  BtfStack fewerViews(b.lights, {b.views[0]}, 4, 3, SampleType::Half);
  test::expectErrorContaining([&] { checkReferenceMatches(b, fewerViews, "m.nbtf", "ref"); },
                              {"1 view directions, the file 2"});
}

TEST(CompressedSourceCheck, EvalInputsCarrySizesAlphaAndHoldout) {
  Progress::setQuiet(true);
  CompressedBtf b = testing::makeBtf(3, 4, 3);
  BtfStack ref = matchingStack(b);
  CompressedReconstruction rec(b);
  EvalInputs in = compressedEvalInputs(b, ref, rec, "m.nbtf", "ref", 4321);
  EXPECT_EQ(in.alpha, b.alpha);
  EXPECT_EQ(in.holdoutImages, b.holdoutImages);
  NbtfSizes s = computeSizes(b, 4321);
  EXPECT_EQ(in.sizes.total, s.total);
  EXPECT_EQ(in.sizes.fileBytes, 4321u);
  EXPECT_DOUBLE_EQ(in.sizes.ratio(), s.ratio);
  EXPECT_EQ(in.method, "clustered neural, k = 3");
  std::vector<float> a(36), c(36);
  in.reconstruct(4, a.data());
  rec.image(4, c.data());
  EXPECT_EQ(a, c);
}

TEST(CompressedSourceCheck, EvaluationAgreesWithTheCompressorsOwnRmse) {
  // Two independent computations of eq. (10): the trainer's bookkeeping at compress time and
  // this evaluation of the finished material.
  Progress::setQuiet(true);
  testing::TestMaterial m = testing::makeTestMaterial();
  CompressOptions o;
  o.train = testing::quickConfig();
  o.train.holdoutFraction = 0.2;
  o.clusters = 6;
  o.progress = false;
  CompressStats stats;
  CompressedBtf b = compressStack(m.stack, o, stats);
  checkReferenceMatches(b, m.stack, "m.nbtf", "material");
  CompressedReconstruction rec(b);
  EvalOptions eo;
  eo.progress = false;
  eo.blurSampleImages = 2;
  EvalResult r = evaluate(compressedEvalInputs(b, m.stack, rec, "m.nbtf", "material", 0), eo);
  ASSERT_TRUE(r.hasHoldout());
  EXPECT_NEAR(r.training.rmse, stats.rmseTrain, 1e-4);
  EXPECT_NEAR(r.holdout.rmse, stats.rmseHoldout, 1e-4);
}

TEST(CompressedSourceCheck, PcaFileEvaluatesLikeTheCompressorMeasuredIt) {
  Progress::setQuiet(true);
  testing::TestMaterial m = testing::makeTestMaterial();
  CompressOptions o;
  o.pcaBaseline = true;
  o.pcaComponents = 2;
  o.train.holdoutFraction = 0.2;
  o.progress = false;
  CompressStats stats;
  CompressedBtf b = compressStack(m.stack, o, stats);
  CompressedReconstruction rec(b);
  EXPECT_EQ(rec.evaluationsPerImage(), 64);
  EvalOptions eo;
  eo.progress = false;
  eo.blurSampleImages = 2;
  EvalInputs in = compressedEvalInputs(b, m.stack, rec, "p.nbtf", "material", 0);
  EXPECT_EQ(in.method, "PCA, C = 2");
  EXPECT_EQ(in.methodFamily, "pca");
  EXPECT_EQ(in.methodParameter, 2);
  EXPECT_TRUE(in.sizes.pca);
  EXPECT_EQ(in.sizes.total, stats.sizes.total);
  EXPECT_EQ(in.sizes.pcaBasis, 81u * 3 * 2 * 4);
  EvalResult r = evaluate(in, eo);
  ASSERT_TRUE(r.hasHoldout());
  EXPECT_NEAR(r.training.rmse, stats.rmseTrain, 1e-6);
  EXPECT_NEAR(r.holdout.rmse, stats.rmseHoldout, 1e-6);
}

TEST(CompressedSourceCheck, RejectsADecoderOfTheWrongShape) {
  CompressedBtf b = testing::makeBtf(3, 4, 3);
  auto& last = b.decoder.layers.back();  // a well-formed layer of 4 outputs where RGB's 3 belong
  last.out = 4;
  last.weight.resize(static_cast<std::size_t>(last.in) * 4, 0.1f);
  last.bias.resize(4, 0.0f);
  test::expectErrorContaining([&] { CompressedReconstruction rec(b); }, {"outputs 4 values, expected 3 (RGB)"});
}

}  // namespace
}  // namespace nbtf
