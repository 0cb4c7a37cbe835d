// The PCA baseline's compression: exact on rank-C data, error falling with C, clear errors
// for impossible component counts, hold-out images kept out of the fit (the neural
// methods' choice) and interpolated, deterministic bytes.
#include "pipeline/pca_compressor.h"

#include <gtest/gtest.h>

#include <random>

#include "codec/pca_model.h"
#include "model/training_set.h"
#include "model_test_material.h"
#include "test_util.h"
#include "util/progress.h"

namespace nbtf {
namespace {

// An 8 x 6-texel stack on 9 x 9 directions whose ABRDFs are exactly mean + rank-`rank`
// combinations: every value a multiple of 1/64 below 4, so the half-float storage holds it
// exactly and nothing but the model's rank limits the reconstruction.
BtfStack rankStack(int rank, unsigned seed = 3) {
  testing::TestMaterial base = testing::makeTestMaterial(8, 6);
  BtfStack stack(base.stack.lights(), base.stack.views(), 8, 6, SampleType::Half);
  const int texels = stack.numTexels(), images = stack.numImages();
  std::mt19937 rng(seed);
  std::vector<int> coefficients(static_cast<std::size_t>(texels) * rank);
  for (int& c : coefficients) c = static_cast<int>(rng() % 4);
  std::vector<float> rgb(static_cast<std::size_t>(texels) * 3);
  for (int i = 0; i < images; ++i) {
    for (int t = 0; t < texels; ++t)
      for (int c = 0; c < 3; ++c) {
        const int d = 3 * i + c;
        int sixtyFourths = 16 + (d * 5) % 32;  // the mean ABRDF
        for (int k = 0; k < rank; ++k) sixtyFourths += coefficients[t * rank + k] * ((d * (k + 3) + k) % 9);
        rgb[3 * t + c] = static_cast<float>(sixtyFourths) / 64.0f;
      }
    stack.setImageLinear(i, rgb.data());
  }
  return stack;
}

CompressOptions pcaOptions(int components, double holdout = 0, std::uint64_t seed = 1) {
  CompressOptions o;
  o.pcaBaseline = true;
  o.pcaComponents = components;
  o.train.holdoutFraction = holdout;
  o.train.seed = seed;
  o.progress = false;
  return o;
}

TEST(PcaCompressor, RankCDataIsReconstructedExactly) {
  BtfStack stack = rankStack(3);
  CompressStats stats;
  CompressedBtf b = compressPcaStack(stack, pcaOptions(3), stats);
  EXPECT_EQ(b.method, CodecMethod::Pca);
  EXPECT_EQ(b.pcaComponents(), 3);
  EXPECT_LT(stats.rmseTrain, 1e-6);
  EXPECT_NEAR(stats.pcaExplainedVarianceRatio, 1.0, 1e-5);
  EXPECT_EQ(stats.rmseHoldout, -1);
  // One component fewer cannot represent it.
  CompressStats fewer;
  compressPcaStack(stack, pcaOptions(2), fewer);
  EXPECT_GT(fewer.rmseTrain, 1e-3);
}

TEST(PcaCompressor, RmseFallsAsComponentsGrow) {
  Progress::setQuiet(true);
  testing::TestMaterial m = testing::makeTestMaterial();
  double previous = testing::imageMeanRmse(m);  // C = 0 would be the mean ABRDF; any C beats the image mean
  double explained = 0;
  // The material is 4 classes x a per-texel brightness: rank 4, so C = 4 reaches the
  // half-float storage's precision.
  for (int c : {1, 2, 3, 4}) {
    CompressStats stats;
    CompressedBtf b = compressPcaStack(m.stack, pcaOptions(c), stats);
    EXPECT_LT(stats.rmseTrain, previous) << "C = " << c;
    EXPECT_GT(stats.pcaExplainedVarianceRatio, explained) << "C = " << c;
    previous = stats.rmseTrain;
    explained = stats.pcaExplainedVarianceRatio;
    EXPECT_EQ(stats.sizes.pcaBasis, 81u * 3 * c * 4);
    EXPECT_EQ(stats.sizes.total, stats.sizes.pcaMean + stats.sizes.pcaBasis + stats.sizes.pcaCoefficients);
  }
  EXPECT_LT(previous, 1e-3);
}

TEST(PcaCompressor, ImpossibleComponentCountsAreClearErrors) {
  testing::TestMaterial m = testing::makeTestMaterial(4, 4);  // 16 texels, 81 images
  CompressStats stats;
  test::expectErrorContaining([&] { compressPcaStack(m.stack, pcaOptions(0), stats); },
                              {"--components must be >= 1"});
  test::expectErrorContaining([&] { compressPcaStack(m.stack, pcaOptions(17), stats); },
                              {"--components 17", "at most 16 = min(16 texels, 3 x 81 images)"});
  // Few images: 3 x the fitted images bind, and held-out images do not count.
  std::vector<Direction> two = {m.stack.lights()[0], m.stack.lights()[3]};
  BtfStack small(two, two, 4, 4, SampleType::Half);
  std::vector<float> rgb(16 * 3, 0.5f);
  for (int i = 0; i < 4; ++i) rgb[i] = 0.1f * i, small.setImageLinear(i, rgb.data());
  test::expectErrorContaining([&] { compressPcaStack(small, pcaOptions(10, 0.25), stats); },
                              {"at most 9 = min(16 texels, 3 x 3 fitted (not held-out) images)"});
  EXPECT_NO_THROW(compressPcaStack(small, pcaOptions(9, 0.25), stats));
}

TEST(PcaCompressor, HoldoutImagesAreTheNeuralOnesLeftOutOfTheFitAndInterpolated) {
  BtfStack stack = rankStack(3);
  CompressStats first;
  CompressedBtf a = compressPcaStack(stack, pcaOptions(3, 0.2, 5), first);
  ASSERT_EQ(a.holdoutImages.size(), 16u);  // round(0.2 x 81)
  EXPECT_EQ(first.holdoutImages, 16);

  // The same images the neural methods hold out for this fraction and seed.
  testing::TestMaterial m = testing::makeTestMaterial(8, 6);
  TrainingSet neural(m.perTexel(), 0.2, 5, false);
  EXPECT_EQ(a.holdoutImages, neural.holdoutImages());

  // Their rows are the interpolation of the fitted rows (the documented rule).
  std::vector<std::uint8_t> fitted(81, 1);
  for (int h : a.holdoutImages) fitted[h] = 0;
  DirectionInterpolator interp(stack.lights(), stack.views(), fitted);
  const int h = a.holdoutImages[0];
  std::vector<float> mean(3), basis(9);
  combinePcaRows(a.pcaMean.data(), a.pcaBasis.data(), 3, interp.weights(stack.lights()[h / 9], stack.views()[h % 9]),
                 mean.data(), basis.data());
  EXPECT_EQ(mean, std::vector<float>(a.pcaMean.begin() + 3 * h, a.pcaMean.begin() + 3 * h + 3));
  EXPECT_EQ(basis, std::vector<float>(a.pcaBasis.begin() + 9 * h, a.pcaBasis.begin() + 9 * h + 9));

  // Garbage in the held-out images changes nothing stored: they are not in the fit.
  BtfStack noisy = stack;
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(0.0f, 0.5f);
  std::vector<float> rgb(static_cast<std::size_t>(stack.numTexels()) * 3);
  for (int held : a.holdoutImages) {
    for (float& x : rgb) x = u(rng);
    noisy.setImageLinear(held, rgb.data());
  }
  CompressStats second;
  CompressedBtf b = compressPcaStack(noisy, pcaOptions(3, 0.2, 5), second);
  EXPECT_EQ(b.holdoutImages, a.holdoutImages);
  EXPECT_LT(second.rmseTrain, 1e-6);
  EXPECT_EQ(b.pcaMean, a.pcaMean);
  EXPECT_EQ(b.pcaBasis, a.pcaBasis);
  EXPECT_EQ(b.latents, a.latents);
  // ...but the hold-out error is measured against them.
  EXPECT_NE(second.rmseHoldout, first.rmseHoldout);
}

TEST(PcaCompressor, SameSeedSameBytes) {
  testing::TestMaterial m = testing::makeTestMaterial();
  CompressStats s1, s2;
  auto a = serializeNbtf(compressPcaStack(m.stack, pcaOptions(4, 0.1, 7), s1));
  auto b = serializeNbtf(compressPcaStack(m.stack, pcaOptions(4, 0.1, 7), s2));
  EXPECT_EQ(a, b);
}

}  // namespace
}  // namespace nbtf
