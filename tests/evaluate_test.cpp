// The evaluation pass: metrics agree with a direct computation, direction pairs are found
// (exactly or nearest), the worst pair and the blur are right, bad reconstructions fail loudly.
#include "eval/evaluate.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <set>

#include "eval_fixtures.h"
#include "test_util.h"
#include "util/progress.h"

namespace nbtf {
namespace {

struct Direct {
  double rmse = 0, rmseHoldout = 0, rmseTraining = 0;
  int worst = -1;
};

// The metrics computed the plain way, independent of ErrorTable.
Direct directMetrics(const BtfStack& ref, const std::function<void(int, float*)>& rec, float alpha,
                     const std::vector<int>& holdout) {
  std::size_t n = static_cast<std::size_t>(ref.numTexels()) * 3;
  std::vector<float> a(n), b(n);
  double all = 0, held = 0, worstMse = -1;
  std::size_t heldCount = 0;
  Direct d;
  for (int i = 0; i < ref.numImages(); ++i) {
    ref.imageLinear(i, a.data());
    rec(i, b.data());
    double s = 0;
    for (std::size_t k = 0; k < n; ++k) s += std::pow((double(a[k]) - b[k]) / alpha, 2);
    all += s;
    if (std::find(holdout.begin(), holdout.end(), i) != holdout.end()) held += s, heldCount += n;
    if (s / n > worstMse) worstMse = s / n, d.worst = i;
  }
  std::size_t total = n * ref.numImages();
  d.rmse = std::sqrt(all / total);
  d.rmseHoldout = heldCount ? std::sqrt(held / heldCount) : 0;
  d.rmseTraining = std::sqrt((all - held) / (total - heldCount));
  return d;
}

class Evaluate : public ::testing::Test {
 protected:
  void SetUp() override { Progress::setQuiet(true); }
};

TEST_F(Evaluate, MetricsMatchADirectComputation) {
  BtfStack ref = testing::syntheticStack(hemisphere81(), hemisphere81(), 6, 5);
  EvalInputs in;
  in.reference = &ref;
  in.alpha = 0.8f;
  in.reconstruct = testing::blurredReconstruction(ref, 0.9, 0.3);
  in.holdoutImages = {7, 300, 6560, 42};
  EvalOptions o;
  o.progress = false;
  EvalResult r = evaluate(in, o);
  Direct d = directMetrics(ref, in.reconstruct, 0.8f, in.holdoutImages);
  EXPECT_NEAR(r.all.rmse, d.rmse, 1e-9);
  EXPECT_NEAR(r.holdout.rmse, d.rmseHoldout, 1e-9);
  EXPECT_NEAR(r.training.rmse, d.rmseTraining, 1e-9);
  EXPECT_EQ(r.worstImage, d.worst);
  EXPECT_EQ(r.all.count, 6561u * 30 * 3);
  EXPECT_EQ(r.byLightElevation.size(), 6u);
  EXPECT_EQ(r.byViewElevation.size(), 6u);
  EXPECT_EQ(r.byViewElevation[5].directions, 24);
  // The gain grows with the view elevation, so the grazing ring has the largest error.
  EXPECT_GT(r.byViewElevation[5].error.rmse, r.byViewElevation[0].error.rmse);
  EXPECT_FALSE(r.alphaFromReference);
  // The blur sample spreads over the (light, view) square: 8 distinct lights, not the diagonal.
  std::set<int> lights;
  int diagonal = 0;
  for (const auto& s : r.blurSamples) lights.insert(s.light), diagonal += s.light == s.view;
  EXPECT_GE(lights.size(), 8u);
  EXPECT_LE(diagonal, 1);
}

// Graininess: the mean brightness map (per texel, over all images) of a hand-made case.
TEST_F(Evaluate, MeanBrightnessMapRmseOfAHandMadeCase) {
  BtfStack ref = testing::syntheticStack(hemisphere81(), hemisphere81(), 4, 3);
  const std::size_t n = 3 * 12;
  // Reconstruction = reference + a per-texel offset that alternates in sign over images:
  // image errors are large, but the mean maps differ only by the offset's mean.
  EvalInputs in;
  in.reference = &ref;
  in.alpha = 2.0f;
  in.reconstruct = [&](int image, float* out) {
    ref.imageLinear(image, out);
    for (std::size_t j = 0; j < n; ++j) out[j] += (image % 2 ? -0.3f : 0.3f) + (j == 5 ? 0.1f : 0.0f);
  };
  EvalOptions o;
  o.progress = false;
  EvalResult r = evaluate(in, o);
  // 6561 images: one more +0.3 than -0.3, so every texel's mean moves by 0.3 / 6561, and
  // value 5 by 0.1 more; divided by alpha.
  const double shift = 0.3 / 6561;
  const double expected = std::sqrt((35 * shift * shift + (shift + 0.1) * (shift + 0.1)) / 36) / 2.0;
  EXPECT_NEAR(r.meanMapRmse, expected, 1e-7);
  EXPECT_GT(r.all.rmse, 0.1);
  EXPECT_EQ(r.meanMapFigure.width > 0, true);
  EXPECT_LT(r.floorRmse, 0);  // no clusters given: no floor
}

TEST_F(Evaluate, ClusterFloorIsComputedForClusteredInputs) {
  BtfStack ref = testing::syntheticStack(hemisphere81(), hemisphere81(), 4, 3);
  EvalInputs in;
  in.reference = &ref;
  in.alpha = 1.0f;
  in.reconstruct = [&](int image, float* out) { ref.imageLinear(image, out); };
  in.clusters = 2;
  in.clusterIds = {0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1};
  EvalOptions o;
  o.progress = false;
  EvalResult r = evaluate(in, o);
  // Direct: every texel against its cluster's mean, per image and channel.
  double sse = 0;
  std::vector<float> rgb(36);
  for (int i = 0; i < ref.numImages(); ++i) {
    ref.imageLinear(i, rgb.data());
    for (int c = 0; c < 3; ++c) {
      double mean[2] = {0, 0};
      for (int t = 0; t < 12; ++t) mean[in.clusterIds[t]] += rgb[3 * t + c] / 6.0;
      for (int t = 0; t < 12; ++t) sse += std::pow(rgb[3 * t + c] - mean[in.clusterIds[t]], 2);
    }
  }
  EXPECT_NEAR(r.floorRmse, std::sqrt(sse / (36.0 * ref.numImages())), 1e-6);
  EXPECT_LT(r.floorRmseModulated, 0);
  EXPECT_EQ(r.meanMapRmse, 0.0);
}

TEST_F(Evaluate, FindsThePaperPairsAndTheWorstPair) {
  BtfStack ref = testing::syntheticStack(hemisphere81(), hemisphere81(), 12, 12);
  EvalInputs in;
  in.reference = &ref;
  in.reconstruct = testing::blurredReconstruction(ref, 1.2, 0.02);
  EvalOptions o;
  o.progress = false;
  o.blurSampleImages = 3;
  EvalResult r = evaluate(in, o);
  ASSERT_EQ(r.comparisons.size(), 3u);
  const auto& top = r.comparisons[0];
  EXPECT_TRUE(top.exact);
  EXPECT_EQ(r.views[top.view], (Direction{15, 60}));
  EXPECT_EQ(r.lights[top.light], (Direction{30, 60}));
  const auto& grazing = r.comparisons[1];
  EXPECT_TRUE(grazing.exact);
  EXPECT_EQ(r.views[grazing.view], (Direction{75, 345}));
  EXPECT_EQ(r.lights[grazing.light], (Direction{75, 0}));
  EXPECT_EQ(r.comparisons[2].image, r.worstImage);
  // alpha defaults to the reference maximum.
  float lo, hi;
  ref.valueRange(lo, hi);
  EXPECT_TRUE(r.alphaFromReference);
  EXPECT_EQ(r.alpha, hi);
  // Every comparison has a figure and a blur estimate close to the true 1.2 texels.
  for (const auto& c : r.comparisons) {
    EXPECT_GT(c.figure.width, 3 * 12);
    EXPECT_NEAR(c.blur.sigma, 1.2, 0.12) << c.name;
    EXPECT_LT(c.blur.rmseAfter, c.blur.rmseBefore);
    EXPECT_NEAR(c.error.rmse, r.table.image(c.image).rmse, 0);
  }
  EXPECT_NEAR(r.blurSigmaMedian, 1.2, 0.12);
  EXPECT_GE(r.blurSamples.size(), 4u);
}

TEST_F(Evaluate, UsesTheNearestDirectionsWhenThePairIsNotMeasured) {
  BtfStack ref = testing::syntheticStack({{0, 0}, {40, 50}}, {{10, 70}, {70, 340}}, 4, 4);
  EvalInputs in;
  in.reference = &ref;
  in.reconstruct = testing::blurredReconstruction(ref, 0.5);
  EvalOptions o;
  o.progress = false;
  EvalResult r = evaluate(in, o);
  EXPECT_FALSE(r.comparisons[0].exact);
  EXPECT_EQ(r.comparisons[0].light, 1);  // (40, 50) is nearest to (30, 60)
  EXPECT_EQ(r.comparisons[0].view, 0);   // (10, 70) is nearest to (15, 60)
  EXPECT_EQ(r.comparisons[1].view, 1);   // (70, 340) is nearest to (75, 345)
}

TEST_F(Evaluate, NonFiniteReconstructionNamesTheImage) {
  BtfStack ref = testing::syntheticStack({{0, 0}, {30, 0}}, {{0, 0}, {45, 90}}, 3, 3);
  EvalInputs in;
  in.reference = &ref;
  in.reconstruct = [&](int image, float* out) {
    ref.imageLinear(image, out);
    if (image == 3) out[7] = std::numeric_limits<float>::quiet_NaN();
  };
  EvalOptions o;
  o.progress = false;
  test::expectErrorContaining([&] { evaluate(in, o); },
                              {"image 3", "light (30\xC2\xB0, 0\xC2\xB0)", "view (45\xC2\xB0, 90\xC2\xB0)", "texel 2",
                               "not finite"});
  // A reconstruction that leaves values unwritten is caught the same way.
  in.reconstruct = [&](int image, float* out) {
    if (image != 2) ref.imageLinear(image, out);
  };
  test::expectErrorContaining([&] { evaluate(in, o); }, {"image 2", "not finite"});
}

TEST_F(Evaluate, RejectsBadInputs) {
  BtfStack ref = testing::syntheticStack({{0, 0}}, {{0, 0}}, 2, 2);
  EvalInputs in;
  in.reference = &ref;
  EvalOptions o;
  o.progress = false;
  test::expectErrorContaining([&] { evaluate(in, o); }, {"no reconstruction"});
  in.reconstruct = [&](int image, float* out) { ref.imageLinear(image, out); };
  in.holdoutImages = {1};
  test::expectErrorContaining([&] { evaluate(in, o); }, {"hold-out", "outside"});
  in.holdoutImages = {};
  BtfStack black({{0, 0}}, {{0, 0}}, 2, 2, SampleType::Srgb8);
  in.reference = &black;
  test::expectErrorContaining([&] { evaluate(in, o); }, {"black", "alpha"});
}

TEST_F(Evaluate, PerfectReconstructionHasZeroErrorAndNoBlur) {
  BtfStack ref = testing::syntheticStack({{0, 0}, {30, 0}}, {{0, 0}, {45, 90}}, 8, 8);
  EvalInputs in;
  in.reference = &ref;
  in.reconstruct = [&](int image, float* out) { ref.imageLinear(image, out); };
  EvalOptions o;
  o.progress = false;
  EvalResult r = evaluate(in, o);
  EXPECT_EQ(r.all.rmse, 0.0);
  EXPECT_TRUE(std::isinf(r.all.psnr));
  for (const auto& s : r.blurSamples) EXPECT_LT(s.estimate.sigma, 0.3);
  for (const auto& c : r.comparisons) EXPECT_EQ(c.magnification, 1.0);
}

}  // namespace
}  // namespace nbtf
