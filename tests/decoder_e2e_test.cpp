// End to end on a trained material: compress a small smooth synthetic BTF, decode the
// .nbtf to an image stack on disk, load it back, and find the compressor's own error;
// unmeasured angles decode to finite values between those of the measured neighbours.
#include <gtest/gtest.h>

#include <cmath>

#include "pipeline/compressor.h"
#include "codec/decoder.h"
#include "pipeline/decoder_output.h"
#include "codec_fixtures.h"
#include "io/btf_loader.h"
#include "test_util.h"
#include "util/progress.h"

namespace nbtf {
namespace {

// RMSE over every texel, image and channel of `decoded` against `source`, both divided by
// alpha (the space the compressor reports, eq. 10).
double rmseNormalized(const BtfStack& decoded, const BtfStack& source, float alpha) {
  double sse = 0;
  for (int i = 0; i < source.numImages(); ++i)
    for (int t = 0; t < source.numTexels(); ++t)
      for (int c = 0; c < 3; ++c) sse += std::pow((decoded.sample(i, t, c) - source.sample(i, t, c)) / alpha, 2);
  return std::sqrt(sse / (3.0 * source.numImages() * source.numTexels()));
}

TEST(DecoderEndToEnd, DecodedStackReproducesTheCompressorsError) {
  Progress::setQuiet(true);
  testing::TestMaterial m = testing::makeTestMaterial();
  CompressOptions o;
  o.train = testing::quickConfig();
  o.train.epochs = 300;
  o.clusters = 4;
  o.progress = false;
  CompressStats stats;
  CompressedBtf b = compressStack(m.stack, o, stats);
  b.layout = Layout::Ubo2003;  // linear-sRGB EXRs: no colour conversion in the round trip
  test::TempDir dir;
  writeNbtf(dir / "m.nbtf", b);
  NbtfDecoder dec = NbtfDecoder::open(dir / "m.nbtf");
  EXPECT_TRUE(dec.clustered());
  EXPECT_EQ(dec.latentRows(), 4);

  DecodeStackOptions out;
  out.format = ImageFormat::Exr;
  writeDecodedStack(dec, dir / "exr", out);
  LoadOptions lo;
  lo.progress = false;
  BtfStack loaded = loadBtfStack(dir / "exr", lo);
  ASSERT_EQ(loaded.numImages(), m.stack.numImages());
  ASSERT_EQ(loaded.lights(), m.stack.lights());
  // The files differ from the model only by half-float rounding (and clamping negatives,
  // which can only bring values closer to the non-negative source).
  double rmse = rmseNormalized(loaded, m.stack, b.alpha);
  EXPECT_NEAR(rmse, stats.rmseTrain, 2e-3 * std::max(stats.rmseTrain, 0.05)) << "compressor: " << stats.rmseTrain;
  EXPECT_LT(rmse, 0.1);

  // Unmeasured: halfway between two measured lights of a meridian, at a measured view.
  // The material is smooth there, and so must the decoder be (within a small margin).
  const Direction a{15, 60}, c{30, 60}, mid{22.5, 60}, view{0, 0};
  for (int t = 0; t < dec.numTexels(); ++t) {
    Rgb va = dec.evaluate(t % 8, t / 8, a, view), vc = dec.evaluate(t % 8, t / 8, c, view);
    Rgb vm = dec.evaluate(t % 8, t / 8, mid, view);
    const float am[3] = {va.r, va.g, va.b}, cm[3] = {vc.r, vc.g, vc.b}, mm[3] = {vm.r, vm.g, vm.b};
    for (int ch = 0; ch < 3; ++ch) {
      ASSERT_TRUE(std::isfinite(mm[ch]));
      float lo = std::min(am[ch], cm[ch]), hi = std::max(am[ch], cm[ch]), margin = 0.25f * (hi - lo) + 0.02f * b.alpha;
      EXPECT_GE(mm[ch], lo - margin) << "texel " << t << " channel " << ch;
      EXPECT_LE(mm[ch], hi + margin) << "texel " << t << " channel " << ch;
    }
  }
  Progress::setQuiet(false);
}

}  // namespace
}  // namespace nbtf
