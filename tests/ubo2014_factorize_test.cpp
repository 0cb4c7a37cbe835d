#include "preprocess/ubo2014_factorize.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>

#include "io/btf_loader.h"
#include "test_util.h"
#include "util/error.h"
#include "util/half.h"

namespace nbtf {
namespace {

// A positive material of low rank in each colour: sums of (direction term) x (texel term).
BtfStack lowRankStack(int w, int h) {
  std::vector<Direction> lights = {{0, 0}, {11, 15}, {30, 105}, {45, 200}, {60, 330}};
  std::vector<Direction> views = {{0, 0}, {23.5, 30}, {52.5, 97.5}, {75, 345}};
  BtfStack s(lights, views, w, h, SampleType::Half);
  std::vector<float> img(static_cast<std::size_t>(w) * h * 3);
  for (int i = 0; i < s.numImages(); ++i) {
    for (int t = 0; t < w * h; ++t)
      for (int c = 0; c < 3; ++c)
        img[t * 3 + c] = 0.5f + 0.1f * std::sin(0.7f * i + c) * std::cos(0.3f * t) + 0.05f * std::cos(1.3f * i) * (t % 5) / 4;
    s.setImageLinear(i, img.data());
  }
  return s;
}

TEST(Ubo2014Factorize, RoundTripThroughAFileKeepsValuesWithinHalfPrecision) {
  test::TempDir dir;
  BtfStack stack = lowRankStack(6, 5);
  for (std::int32_t model : {0, 11}) {
    Ubo2014FactorizeOptions o;
    o.progress = false;
    o.colorModel = model;
    o.components = 20;  // the full rank: 20 light/view pairs
    Ubo2014FactorizeReport report;
    Ubo2014Btf btf = factorizeUbo2014(stack, o, &report);
    EXPECT_EQ(report.components, 20);
    EXPECT_LT(report.rmseLinear, 2e-3 * report.inputMean) << "model " << model;

    const std::string path = dir / ("rt" + std::to_string(model) + ".btf");
    btf.write(path);
    LoadOptions load;
    load.progress = false;
    BtfStack back = loadBtfStack(path, load);
    ASSERT_EQ(back.numImages(), stack.numImages());
    ASSERT_EQ(back.lights(), stack.lights());
    ASSERT_EQ(back.views(), stack.views());
    double worst = 0;
    for (int i = 0; i < stack.numImages(); ++i)
      for (int t = 0; t < stack.numTexels(); ++t)
        for (int c = 0; c < 3; ++c) {
          const float a = stack.sample(i, t, c), b = back.sample(i, t, c);
          worst = std::max(worst, static_cast<double>(std::abs(a - b)));
        }
    // stored factors are half floats (2^-11 = 4.9e-4 relative each), the stack too: a few
    // half-precision steps of the values (0.35 to 0.65)
    EXPECT_LT(worst, 4e-3 * report.inputMean) << "model " << model;
  }
}

TEST(Ubo2014Factorize, TruncationKeepsTheLeadingComponents) {
  BtfStack stack = lowRankStack(8, 8);
  Ubo2014FactorizeOptions o;
  o.progress = false;
  o.colorModel = 0;
  double previous = 1e9;
  for (int k : {1, 2, 4}) {
    o.components = k;
    Ubo2014FactorizeReport r;
    Ubo2014Btf btf = factorizeUbo2014(stack, o, &r);
    EXPECT_EQ(btf.channels()[0].components, k);
    EXPECT_LE(r.rmseLinear, previous);
    previous = r.rmseLinear;
    // singular values descend
    const auto& s = btf.channels()[0].s;
    for (std::size_t j = 1; j < s.size(); ++j) EXPECT_GE(s[j - 1], s[j]);
  }
  // the input is rank 2 per channel (plus the constant): 4 components reproduce it
  EXPECT_LT(previous, 1e-3);
}

// Over its memory limit the factorization holds nothing of the material's size: it asks for
// every image again in each pass, and gives the factors of the held matrices.
TEST(Ubo2014Factorize, StreamedPassesGiveTheHeldFactorization) {
  BtfStack stack = lowRankStack(40, 30);  // 1200 texels: more than one slice of texels
  std::atomic<int> calls{0};
  auto image = [&](int i, float* rgb) {
    ++calls;
    stack.imageLinear(i, rgb);
  };
  for (std::int32_t model : {0, 11}) {
    Ubo2014FactorizeOptions held;
    held.progress = false;
    held.colorModel = model;
    held.components = 6;
    Ubo2014FactorizeReport heldReport;
    calls = 0;
    const Ubo2014Btf a = factorizeUbo2014(stack.lights(), stack.views(), 40, 30, image, held, &heldReport);
    EXPECT_EQ(calls.load(), 20);
    EXPECT_FALSE(heldReport.streamed);
    EXPECT_EQ(heldReport.passes, 1);

    Ubo2014FactorizeOptions streamed = held;
    streamed.memoryLimit = ubo2014MatrixBytes(20, 1200) - 1;
    streamed.blockBytes = 1;  // two images per thread in each block: several blocks
    Ubo2014FactorizeReport report;
    calls = 0;
    const Ubo2014Btf b = factorizeUbo2014(stack.lights(), stack.views(), 40, 30, image, streamed, &report);
    EXPECT_TRUE(report.streamed);
    EXPECT_EQ(report.passes, 2 + 2 * streamed.powerIterations + 1);
    EXPECT_EQ(calls.load(), 20 * report.passes);
    EXPECT_NEAR(report.rmseLinear, heldReport.rmseLinear, 1e-3 * heldReport.rmseLinear + 1e-7) << "model " << model;
    EXPECT_NEAR(report.inputMean, heldReport.inputMean, 1e-6 * heldReport.inputMean);

    // the same values (half-float factors of the same SVD, summed in another order)
    std::vector<float> va(1200 * 3), vb(1200 * 3);
    double worst = 0;
    for (int i = 0; i < 20; ++i) {
      a.imageLinear(i, va.data());
      b.imageLinear(i, vb.data());
      for (std::size_t j = 0; j < va.size(); ++j) worst = std::max(worst, static_cast<double>(std::abs(va[j] - vb[j])));
    }
    EXPECT_LT(worst, 2e-3 * heldReport.inputMean) << "model " << model;

    // deterministic: the same factors again, bit for bit; without a report one pass less
    calls = 0;
    const Ubo2014Btf c = factorizeUbo2014(stack.lights(), stack.views(), 40, 30, image, streamed);
    EXPECT_EQ(calls.load(), 20 * (report.passes - 1));
    for (int ch = 0; ch < 3; ++ch) {
      EXPECT_EQ(c.channels()[ch].u, b.channels()[ch].u);
      EXPECT_EQ(c.channels()[ch].sxv, b.channels()[ch].sxv);
    }
  }
}

// A bright material's largest singular value passes half's range: it is stored as the largest
// half (decoding does not use it), so that the file reads back; the values are unchanged.
TEST(Ubo2014Factorize, SingularValuesOverTheHalfRangeAreStoredAsTheLargestHalf) {
  test::TempDir dir;
  BtfStack stack = lowRankStack(40, 30);
  BtfStack bright(stack.lights(), stack.views(), 40, 30, SampleType::Half);
  std::vector<float> img(1200 * 3);
  for (int i = 0; i < stack.numImages(); ++i) {
    stack.imageLinear(i, img.data());
    for (float& v : img) v *= 1e4f;
    bright.setImageLinear(i, img.data());
  }
  Ubo2014FactorizeOptions o;
  o.progress = false;
  o.colorModel = 0;
  o.components = 4;
  Ubo2014FactorizeReport report;
  const Ubo2014Btf btf = factorizeUbo2014(bright, o, &report);
  EXPECT_EQ(btf.channels()[0].s[0], 65504.0f);
  EXPECT_LT(btf.channels()[0].s[3], 65504.0f);
  const std::string path = dir / "bright.btf";
  btf.write(path);
  const Ubo2014Btf back = Ubo2014Btf::read(path);
  EXPECT_EQ(back.channels()[0].s, btf.channels()[0].s);
  EXPECT_LT(report.rmseLinear, 2e-3 * report.inputMean);
}

TEST(Ubo2014Factorize, RefusesWhatItCannotWrite) {
  BtfStack stack = lowRankStack(2, 2);
  Ubo2014FactorizeOptions o;
  o.progress = false;
  o.colorModel = 2;
  EXPECT_THROW(checkUbo2014FactorizeOptions(o), Error);
  EXPECT_THROW(factorizeUbo2014(stack, o), Error);
  o.colorModel = 0;
  o.components = 0;
  EXPECT_THROW(factorizeUbo2014(stack, o), Error);
}

}  // namespace
}  // namespace nbtf
