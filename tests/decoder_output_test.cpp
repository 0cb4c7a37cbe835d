// Decoding to image stacks: the files load back with the stack loader and hold the
// model's values (8-bit sRGB within quantization, EXR = output x alpha at half precision),
// names and subsets, unmeasured angles, tiling, and bad input.
#include "pipeline/decoder_output.h"
#include "pipeline/decoded_image_names.h"

#include <gtest/gtest.h>

#include <Imath/half.h>

#include <cmath>
#include <cstring>
#include <filesystem>

#include "decoder_fixtures.h"
#include "io/btf_loader.h"
#include "io/btf_names.h"
#include "io/color.h"
#include "test_util.h"
#include "util/atomic_file.h"
#include "util/progress.h"

namespace nbtf {
namespace {

namespace fs = std::filesystem;
using testing::makeDisplayableMaterial;
using testing::referenceOutput;

class DecoderOutput : public ::testing::Test {
 protected:
  void SetUp() override { Progress::setQuiet(true); }
  void TearDown() override { Progress::setQuiet(false); }
};

LoadOptions quietLoad() {
  LoadOptions o;
  o.progress = false;
  return o;
}

// Every texel of every image of a loaded 8-bit stack against the reference, in sRGB bytes:
// at most 1 code off (float vs double rounding at a code boundary), almost always exact.
void expectStackMatchesModel(const BtfStack& stack, const CompressedBtf& b) {
  std::size_t exact = 0, total = 0;
  for (int l = 0; l < stack.numLights(); ++l)
    for (int v = 0; v < stack.numViews(); ++v) {
      const std::uint8_t* bytes = stack.imageBytes(stack.imageIndex(l, v));
      for (int t = 0; t < stack.numTexels(); ++t) {
        auto ref = referenceOutput(b, t, stack.lights()[l], stack.views()[v]);
        for (int c = 0; c < 3; ++c, ++total) {
          int expect = linearToSrgb8(static_cast<float>(ref[c] * b.alpha));
          int got = bytes[3 * t + c];
          ASSERT_LE(std::abs(got - expect), 1) << "image " << l << "," << v << " texel " << t << " channel " << c;
          exact += got == expect;
        }
      }
    }
  EXPECT_GE(exact, total * 99 / 100);
}

TEST_F(DecoderOutput, PngStackLoadsBackAndMatchesTheModel) {
  for (Layout layout : {Layout::Ubo2003, Layout::Utia})
    for (int k : {4, 0}) {
      CompressedBtf b = makeDisplayableMaterial(k);
      NbtfDecoder dec(b);
      test::TempDir dir;
      DecodeStackOptions o;
      o.layout = layout;
      o.format = ImageFormat::Png;
      DecodeStackResult r = writeDecodedStack(dec, dir.path(), o);
      EXPECT_EQ(r.images, 6);
      EXPECT_EQ(r.evaluations, 6u * static_cast<unsigned>(dec.latentRows()));
      BtfStack stack = loadBtfStack(dir.path(), quietLoad());
      EXPECT_EQ(stack.layout, layout);
      EXPECT_EQ(stack.lights(), b.lights);
      EXPECT_EQ(stack.views(), b.views);
      ASSERT_EQ(stack.width(), b.width);
      ASSERT_EQ(stack.height(), b.height);
      expectStackMatchesModel(stack, b);
      // The in-memory decode is the same bytes.
      BtfStack mem = decodeStack(dec, SampleType::Srgb8, {}, {}, false);
      for (int i = 0; i < stack.numImages(); ++i)
        EXPECT_EQ(std::memcmp(mem.imageBytes(i), stack.imageBytes(i), stack.bytesPerImage()), 0) << "image " << i;
    }
}

TEST_F(DecoderOutput, UsesTheLoadersNames) {
  CompressedBtf b = makeDisplayableMaterial(4);
  NbtfDecoder dec(b);
  test::TempDir dir;
  DecodeStackOptions o;
  o.layout = Layout::Ubo2003;
  o.format = ImageFormat::Jpg;
  writeDecodedStack(dec, dir.path(), o);
  // Image index = light * views + view: light 2 (15, 60) x view 1 (30, 30) is image 5.
  EXPECT_TRUE(fs::exists(dir / "tv030_pv030/00005 tl015 pl060 tv030 pv030.jpg"));
  EXPECT_TRUE(fs::exists(dir / "tv000_pv000/00000 tl000 pl000 tv000 pv000.jpg"));
  o.layout = Layout::Utia;
  o.format = ImageFormat::Png;
  test::TempDir utia;
  writeDecodedStack(dec, utia.path(), o);
  EXPECT_TRUE(fs::exists(utia / "tv030_pv030/tl015_pl060_tv030_pv030.png"));
  // JPEG is lossy: the stack still loads with the right shape.
  BtfStack stack = loadBtfStack(dir.path(), quietLoad());
  EXPECT_EQ(stack.numImages(), 6);
}

TEST_F(DecoderOutput, DefaultsFollowTheSource) {
  CompressedBtf b = makeDisplayableMaterial(4);  // the fixture's source: UTIA, half float
  NbtfDecoder dec(b);
  EXPECT_EQ(resolvedLayout(dec, {}), Layout::Utia);
  EXPECT_EQ(resolvedFormat(dec, {}), ImageFormat::Exr);
  b.layout = Layout::Unknown;
  b.sourceSampleType = SampleType::Srgb8;
  NbtfDecoder dec2(b);
  EXPECT_EQ(resolvedLayout(dec2, {}), Layout::Ubo2003);
  EXPECT_EQ(resolvedFormat(dec2, {}), ImageFormat::Png);
}

TEST_F(DecoderOutput, ExrHoldsModelOutputTimesAlphaAtHalfPrecision) {
  CompressedBtf b = makeDisplayableMaterial(0);
  // Push some outputs below zero: they must come out as 0 and be counted.
  b.decoder.layers.back().bias[2] = -0.05f;
  NbtfDecoder dec(b);
  std::size_t negatives = 0;
  for (int l = 0; l < 3; ++l)
    for (int v = 0; v < 2; ++v)
      for (int t = 0; t < b.numTexels(); ++t)
        for (int c = 0; c < 3; ++c) negatives += referenceOutput(b, t, b.lights[l], b.views[v])[c] < 0;
  ASSERT_GT(negatives, 0u);

  test::TempDir dir;
  DecodeStackOptions o;
  o.layout = Layout::Ubo2003;
  o.format = ImageFormat::Exr;
  DecodeStackResult r = writeDecodedStack(dec, dir.path(), o);
  EXPECT_EQ(r.clampedNegative, negatives);
  for (int l = 0; l < 3; ++l)
    for (int v = 0; v < 2; ++v) {
      std::string path = dir / decodedImagePath(Layout::Ubo2003, ImageFormat::Exr, {b.lights[l], l}, {b.views[v], v}, 2);
      ImageF img = readExr(path);
      ASSERT_EQ(img.width, b.width);
      for (int t = 0; t < b.numTexels(); ++t) {
        auto ref = referenceOutput(b, t, b.lights[l], b.views[v]);
        for (int c = 0; c < 3; ++c) {
          float expect = std::max(0.0f, static_cast<float>(ref[c] * b.alpha));
          // half: 11 significant bits -> relative error <= 2^-11; plus float-vs-double.
          EXPECT_NEAR(img.rgb[3 * t + c], expect, std::fabs(expect) * 4.9e-4 + 1e-6) << path << " texel " << t;
        }
      }
    }
  // The UTIA layout stores CIE XYZ (like the UTIA database); the loader converts it back.
  test::TempDir utia;
  o.layout = Layout::Utia;
  writeDecodedStack(dec, utia.path(), o);
  BtfStack stack = loadBtfStack(utia.path(), quietLoad());
  EXPECT_EQ(stack.sampleType(), SampleType::Half);
  for (int i = 0; i < stack.numImages(); ++i)
    for (int t = 0; t < stack.numTexels(); ++t) {
      auto ref = referenceOutput(b, t, stack.lights()[i / 2], stack.views()[i % 2]);
      for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(stack.sample(i, t, c), std::max(0.0, ref[c] * b.alpha), 4e-3 * std::fabs(ref[c] * b.alpha) + 2e-3)
            << "image " << i << " texel " << t << " channel " << c;
    }
}

// One naming per layout: with an unmeasured angle in a UBO2003 output every image is
// numbered by its place in the output (it used to get a UTIA name among UBO2003 ones).
TEST_F(DecoderOutput, SubsetsAndUnmeasuredAnglesGetTheLayoutsNames) {
  CompressedBtf b = makeDisplayableMaterial(4);
  NbtfDecoder dec(b);
  test::TempDir dir;
  DecodeStackOptions o;
  o.layout = Layout::Ubo2003;
  o.format = ImageFormat::Png;
  o.lights = parseDirectionList("1,t37.5p200", dec.lights(), "--lights");
  o.views = parseDirectionList("0", dec.views(), "--views");
  DecodeStackResult r = writeDecodedStack(dec, dir.path(), o);
  EXPECT_EQ(r.images, 2);
  EXPECT_TRUE(fs::exists(dir / "tv000_pv000/00000 tl015 pl000 tv000 pv000.png"));
  const std::string unmeasured = dir / "tv000_pv000/00001 tl037.500 pl200 tv000 pv000.png";
  ASSERT_TRUE(fs::exists(unmeasured));
  std::size_t files = 0;
  for (auto& e : fs::recursive_directory_iterator(dir.path()))
    files += e.is_regular_file() && e.path().filename() != kDecodeDescriptionName;
  EXPECT_EQ(files, 2u);
  // The unmeasured image holds the model's values at exactly those angles.
  Image8 img = readImage8(unmeasured);
  for (int t = 0; t < b.numTexels(); ++t) {
    auto ref = referenceOutput(b, t, {37.5, 200}, {0, 0});
    for (int c = 0; c < 3; ++c)
      EXPECT_LE(std::abs(int(img.rgb[3 * t + c]) - int(linearToSrgb8(float(ref[c] * b.alpha)))), 1);
  }
  // And the subset loads as a 2-light, 1-view stack.
  BtfStack stack = loadBtfStack(dir.path(), quietLoad());
  EXPECT_EQ(stack.numLights(), 2);
  EXPECT_EQ(stack.numViews(), 1);
}

TEST_F(DecoderOutput, LargerSizesTileTheTexture) {
  CompressedBtf b = makeDisplayableMaterial(4);
  NbtfDecoder dec(b);
  test::TempDir dir;
  DecodeStackOptions o;
  o.format = ImageFormat::Png;
  o.layout = Layout::Utia;
  o.width = 16, o.height = 11;
  o.lights = parseDirectionList("2", dec.lights(), "--lights");
  o.views = parseDirectionList("1", dec.views(), "--views");
  writeDecodedStack(dec, dir.path(), o);
  Image8 big = readImage8(dir / "tv030_pv030/tl015_pl060_tv030_pv030.png");
  ASSERT_EQ(big.width, 16);
  ASSERT_EQ(big.height, 11);
  BtfStack base = decodeStack(dec, SampleType::Srgb8, o.lights, o.views, false);
  for (int y = 0; y < 11; ++y)
    for (int x = 0; x < 16; ++x)
      for (int c = 0; c < 3; ++c)
        EXPECT_EQ(big.rgb[3 * (y * 16 + x) + c], base.imageBytes(0)[3 * ((y % 5) * 7 + x % 7) + c]);
}

TEST_F(DecoderOutput, NonFiniteOrHugeOutputsAreErrors) {
  CompressedBtf b = makeDisplayableMaterial(4);
  b.decoder.layers.back().bias = {3.4e38f, 3.4e38f, 3.4e38f};
  for (float& w : b.decoder.layers.back().weight) w = std::fabs(w) * 1e38f + 1e37f;
  NbtfDecoder dec(b);
  test::TempDir dir;
  DecodeStackOptions o;
  o.format = ImageFormat::Png;
  test::expectErrorContaining([&] { writeDecodedStack(dec, dir.path(), o); }, {"is not finite", "light ("});
  b.decoder.layers.back().bias = {70000.0f, 0.1f, 0.1f};
  for (float& w : b.decoder.layers.back().weight) w = 0;
  NbtfDecoder big(b);
  o.format = ImageFormat::Exr;
  test::expectErrorContaining([&] { writeDecodedStack(big, dir.path(), o); }, {"exceeds the largest half float"});
  // 8-bit formats saturate instead: 70000 encodes to 255.
  o.format = ImageFormat::Png;
  EXPECT_NO_THROW(writeDecodedStack(big, dir.path(), o));
}

TEST_F(DecoderOutput, UnwritableOutputIsAnErrorBeforeAnyWork) {
  NbtfDecoder dec(makeDisplayableMaterial(4));
  test::TempDir dir;
  std::string file = dir / "a_file";
  writeFileAtomic(file, std::string("x"));
  test::expectErrorContaining([&] { writeDecodedStack(dec, file + "/sub", {}); }, {"a_file/sub", "cannot create"});
}

}  // namespace
}  // namespace nbtf
