// Stored parts (codec/nbtf_storage.cpp): coded ids and modulation, 8-bit weights, roundToStorage, storageDescription.
#include "codec/nbtf_file.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "codec/texel_modulation.h"
#include "codec_fixtures.h"
#include "nbtf_file_fixtures.h"
#include "test_util.h"
#include "util/error.h"
#include "util/half.h"

namespace nbtf {
namespace {
using testing::makeBtf;
using testing::makeDecoder;

TEST(NbtfFile, CompactRoundTripIsBitExactAndVersion12) {
  for (int terms : {1, 3})
    for (int bits : {4, 8, 12}) {
      CompressedBtf b = makeCompactBtf(5, terms, bits);
      std::vector<std::uint8_t> bytes = serializeNbtf(b);
      EXPECT_EQ(bytes[10], 2);  // format 1.2
      CompressedBtf back = parseNbtf(bytes.data(), bytes.size(), "mem");
      EXPECT_EQ(serializeNbtf(back), bytes);
      EXPECT_EQ(back.modulation.terms, terms);
      EXPECT_EQ(back.modulation.bits, bits);
      EXPECT_EQ(back.modulation.codes, b.modulation.codes);
      EXPECT_EQ(back.modulation.minimum, b.modulation.minimum);
      EXPECT_EQ(back.modulation.maximum, b.modulation.maximum);
      EXPECT_EQ(back.ids, b.ids);
      EXPECT_EQ(back.latents, b.latents);  // half values: exact after roundToStorage
      EXPECT_EQ(back.decoder.layers[0].weight, b.decoder.layers[0].weight);
      EXPECT_TRUE(back.storage.decoderHalf && back.storage.latentsHalf && back.storage.idsZstd);
    }
  // Per-channel coefficients (format 1.5, section TXCH, which readers before 1.5 refuse as an
  // unknown required section): the same round trip, raw or zstd-coded codes.
  for (bool zstd : {true, false}) {
    CompressedBtf b = makeCompactBtf(5, 2, 6, 3);
    b.storage.modulationZstd = zstd;
    std::vector<std::uint8_t> bytes = serializeNbtf(b);
    EXPECT_EQ(bytes[10], 5);  // format 1.5
    EXPECT_NE(std::search(bytes.begin(), bytes.end(), std::begin("TXCH"), std::begin("TXCH") + 4), bytes.end());
    CompressedBtf back = parseNbtf(bytes.data(), bytes.size(), "mem");
    EXPECT_EQ(serializeNbtf(back), bytes);
    EXPECT_EQ(back.modulation.terms, 2);
    EXPECT_EQ(back.modulation.channels, 3);
    EXPECT_EQ(back.modulation.codes, b.modulation.codes);
    EXPECT_EQ(back.modulation.minimum, b.modulation.minimum);
    EXPECT_EQ(back.modulation.maximum, b.modulation.maximum);
    EXPECT_TRUE(contains(formatSizeTable(computeSizes(back)), "6 coefficients (per RGB channel) x 6-bit codes"));
    // A channel count other than 3 in TXCH is refused, naming the section.
    CompressedBtf bad = b;
    bad.modulation.channels = 2;
    EXPECT_THROW(serializeNbtf(bad), Error);
  }
  // Decorrelated codes (format 1.11, section TXCR): the rotation too, raw or a zstd frame per column.
  for (bool zstd : {true, false}) {
    CompressedBtf b = makeDecorrelatedBtf();
    b.storage.modulationZstd = zstd;
    std::vector<std::uint8_t> bytes = serializeNbtf(b);
    EXPECT_EQ(bytes[10], 11);  // format 1.11
    EXPECT_NE(findSection(bytes, "TXCR"), 0u);
    EXPECT_EQ(findSection(bytes, "TXCH"), 0u);
    CompressedBtf back = parseNbtf(bytes.data(), bytes.size(), "mem");
    EXPECT_EQ(serializeNbtf(back), bytes);
    EXPECT_TRUE(back.modulation.decorrelated);
    EXPECT_EQ(back.modulation.codes, b.modulation.codes);
    EXPECT_EQ(back.modulation.minimum, b.modulation.minimum);
    EXPECT_EQ(back.modulation.rotation, b.modulation.rotation);
    EXPECT_EQ(dequantizeTexelCoefficients(back.modulation), dequantizeTexelCoefficients(b.modulation));
    const std::string description = modulationDescription(back.modulation);
    EXPECT_TRUE(contains(description, "decorrelated")) << description;
  }
  // Each compact part alone also round-trips, and raw modulation codes too.
  for (int part = 0; part < 4; ++part) {
    CompressedBtf b = makeBtf(300, 20, 20);
    if (part == 0) b.storage.decoderHalf = true;
    if (part == 1) b.storage.latentsHalf = true;
    if (part == 2) b.storage.idsZstd = true;  // k = 300: 2-byte ids, two planes
    if (part == 3) {
      b.modulation = quantizeTexelCoefficients(std::vector<float>(400, 1.5f), 1, 16);
      b.storage.modulationZstd = false;
    }
    roundToStorage(b);
    std::vector<std::uint8_t> bytes = serializeNbtf(b);
    CompressedBtf back = parseNbtf(bytes.data(), bytes.size(), "mem");
    EXPECT_EQ(serializeNbtf(back), bytes) << "part " << part;
    EXPECT_EQ(back.ids, b.ids) << "part " << part;
  }
}

// storage.decoder "int8" (DEC8, format 1.4): each weight is a signed 8-bit code times its
// output row's half scale, within half a step of the trained value; the file holds exactly the
// rounded values and reads back to them.
TEST(NbtfFile, Int8DecoderRoundTripsWithinItsStatedError) {
  CompressedBtf b = makeBtf(5);
  std::mt19937 rng(3);
  b.decoder = makeDecoder(b.latentDim, {40, 30}, rng);
  b.decoder.layers[1].weight[7] = 1e-6f;  // a lone tiny weight in a row of ordinary ones
  std::fill_n(b.decoder.layers[1].weight.begin() + 40, 40, 1e-7f);  // a row of tiny weights
  const Mlp trained = b.decoder;
  b.storage.decoderInt8 = true;
  test::expectErrorContaining([&] { serializeNbtf(b); }, {"8-bit weights", "roundToStorage"});
  roundToStorage(b);
  for (std::size_t l = 0; l < trained.layers.size(); ++l) {
    const DenseLayer &t = trained.layers[l], &q = b.decoder.layers[l];
    for (int o = 0; o < t.out; ++o) {
      float largest = 0;
      for (int i = 0; i < t.in; ++i) largest = std::max(largest, std::fabs(t.weight[o * t.in + i]));
      const float step = std::max(largest / 127.f * (1 + 1.f / 1024), 6.103515625e-05f);
      for (int i = 0; i < t.in; ++i)
        ASSERT_LE(std::fabs(q.weight[o * t.in + i] - t.weight[o * t.in + i]), step / 2 + 1e-12f)
            << "layer " << l << " row " << o << " input " << i;
    }
    for (int o = 0; o < t.out; ++o) EXPECT_EQ(q.bias[o], roundToHalf(t.bias[o]));
  }
  const std::vector<std::uint8_t> bytes = serializeNbtf(b);
  EXPECT_EQ(bytes[10], 4);  // format 1.4
  EXPECT_NE(findSection(bytes, "DEC8"), 0u);
  CompressedBtf back = parseNbtf(bytes.data(), bytes.size(), "mem");
  EXPECT_TRUE(back.storage.decoderInt8);
  EXPECT_FALSE(back.storage.decoderHalf);
  for (std::size_t l = 0; l < trained.layers.size(); ++l) {
    EXPECT_EQ(back.decoder.layers[l].weight, b.decoder.layers[l].weight);
    EXPECT_EQ(back.decoder.layers[l].bias, b.decoder.layers[l].bias);
  }
  EXPECT_EQ(serializeNbtf(back), bytes);
  // Rounding again changes nothing.
  roundToStorage(back);
  EXPECT_EQ(serializeNbtf(back), bytes);
  // Sizes: one byte a weight, two for each row's scale and bias.
  NbtfSizes sizes = computeSizes(b);
  std::uint64_t weights = 0, outputs = 0;
  for (const DenseLayer& l : b.decoder.layers) weights += l.weight.size(), outputs += l.bias.size();
  EXPECT_EQ(sizes.decoder, weights + 4 * outputs);
  EXPECT_TRUE(contains(formatSizeTable(sizes), "8-bit weights, half scale per row")) << formatSizeTable(sizes);
  EXPECT_EQ(storageDescription(b), "decoder int8, latents float32, ids raw, directions f64, metadata raw");
}

}  // namespace
}  // namespace nbtf
