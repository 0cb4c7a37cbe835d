// Pieces every compressor shares (pipeline/compress_parts.cpp): the file's frame from its stack, the source record, the stored file's RMSE.
#include "pipeline/compress_parts.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include <nlohmann/json.hpp>

#include "codec/decoder.h"
#include "io/source_fingerprint.h"
#include "codec_fixtures.h"
#include "model_test_material.h"

namespace nbtf {
namespace {

TEST(CompressParts, TheFrameCopiesTheStacksGeometry) {
  testing::TestMaterial m = testing::makeTestMaterial();
  CompressedBtf b = compressedFrame(m.stack, CodecMethod::ClusteredNeural, 2.5f);
  EXPECT_EQ(b.method, CodecMethod::ClusteredNeural);
  EXPECT_EQ(b.width, 8);
  EXPECT_EQ(b.height, 8);
  EXPECT_EQ(b.sourceWidth, 8);  // an in-memory stack: its own size
  EXPECT_EQ(b.sourceHeight, 8);
  EXPECT_TRUE(b.crop.empty());
  EXPECT_EQ(b.lights.size(), 9u);
  EXPECT_EQ(b.views.size(), 9u);
  EXPECT_EQ(b.sourceSampleType, SampleType::Half);
  EXPECT_EQ(b.alpha, 2.5f);
  m.stack.sourceWidth = 100, m.stack.sourceHeight = 60;
  m.stack.crop = Crop{10, 20, 8, 8};
  m.stack.layout = Layout::Utia;
  b = compressedFrame(m.stack, CodecMethod::Pca, 1);
  EXPECT_EQ(b.sourceWidth, 100);
  EXPECT_EQ(b.sourceHeight, 60);
  EXPECT_EQ(b.crop, (Crop{10, 20, 8, 8}));
  EXPECT_EQ(b.layout, Layout::Utia);
}

TEST(CompressParts, SourceRecordHoldsThePathCropAndFingerprint) {
  testing::TestMaterial m = testing::makeTestMaterial();
  m.stack.source = "/data/wool";
  m.stack.layout = Layout::Ubo2003;
  nlohmann::json j = nlohmann::json::parse(sourceMetadataJson(m.stack));
  EXPECT_EQ(j["path"], "/data/wool");
  EXPECT_EQ(j["layout"], "ubo2003");
  EXPECT_EQ(j["sample_type"], "half float (linear)");
  EXPECT_TRUE(j["crop"].is_null());
  // The fingerprint reads back as the stack's own, and matches the stack.
  const nlohmann::json meta = {{"source", j}};
  const auto fp = sourceFingerprintOf(meta.dump(), "m.nbtf");
  ASSERT_TRUE(fp.has_value());
  EXPECT_EQ(sourceFingerprintJson(*fp), sourceFingerprintJson(sourceFingerprint(m.stack)));
  EXPECT_TRUE(checkSourceFingerprint(*fp, m.stack).matches);
  m.stack.crop = Crop{1, 2, 8, 8};
  EXPECT_EQ(nlohmann::json::parse(sourceMetadataJson(m.stack))["crop"], nlohmann::json({1, 2, 8, 8}));
}

// The stored file's RMSE (eq. 10, linear / alpha) on the training and the held-out images,
// against a direct sum over every texel, image and channel.
TEST(CompressParts, DecodedRmseIsTheFilesOwnErrorOnBothImageSets) {
  testing::TestMaterial m = testing::makeTestMaterial(4, 4);
  CompressedBtf b = compressedFrame(m.stack, CodecMethod::ClusteredNeural, m.alpha);
  std::mt19937 rng(5);
  b.latentDim = 4;
  b.decoder = testing::makeDecoder(4, {9}, rng);
  b.latentRows = 4;
  b.latents.assign(16, 0.25f);
  for (int t = 0; t < 16; ++t) b.ids.push_back(m.ids[t]);
  const NbtfDecoder decoder(b);
  std::vector<std::uint8_t> holdout(81, 0);
  holdout[3] = holdout[40] = 1;
  const auto [train, held] = detail::decodedRmse(decoder, m.stack, m.alpha, holdout);
  double sse[2] = {0, 0};
  std::size_t n[2] = {0, 0};
  for (int image = 0; image < 81; ++image) {
    const Direction& l = m.stack.lights()[image / 9];
    const Direction& v = m.stack.views()[image % 9];
    for (int t = 0; t < 16; ++t) {
      const Rgb rgb = decoder.evaluate(t % 4, t / 4, l, v, OutputScale::Normalized);
      const float got[3] = {rgb.r, rgb.g, rgb.b};
      for (int c = 0; c < 3; ++c) {
        const double d = got[c] - m.stack.sample(image, t, c) / m.alpha;
        sse[holdout[image]] += d * d;
        ++n[holdout[image]];
      }
    }
  }
  EXPECT_NEAR(train, std::sqrt(sse[0] / n[0]), 1e-5);
  EXPECT_NEAR(held, std::sqrt(sse[1] / n[1]), 1e-5);
  EXPECT_EQ(detail::decodedRmse(decoder, m.stack, m.alpha, std::vector<std::uint8_t>(81, 0)).second, -1);
}

}  // namespace
}  // namespace nbtf
