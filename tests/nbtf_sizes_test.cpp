// Sizes of a material (codec/nbtf_sizes.cpp): id widths, computeSizes (the paper's Table 1), formatSizeTable.
#include "codec/nbtf_file.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "codec/texel_modulation.h"
#include "codec_fixtures.h"
#include "nbtf_file_fixtures.h"
#include "util/directions.h"

namespace nbtf {
namespace {
using testing::makeDecoder;

// ---- Id widths

TEST(NbtfFile, IdWidthIsTheSmallestThatFitsK) {
  EXPECT_EQ(idWidthForClusters(1), 1);
  EXPECT_EQ(idWidthForClusters(255), 1);
  EXPECT_EQ(idWidthForClusters(256), 1);  // ids 0..255
  EXPECT_EQ(idWidthForClusters(257), 2);
  EXPECT_EQ(idWidthForClusters(65536), 2);  // ids 0..65535
  EXPECT_EQ(idWidthForClusters(65537), 4);
}

// ---- Sizes (Table 1)

// The paper's material shape: 100 x 100 texels, 6561 images, decoder 12 -> 106 -> 106 -> 106
// -> 3, k = 500 (latents and ids all zero).
CompressedBtf paperShapedBtf() {
  std::mt19937 rng(1);
  CompressedBtf b;
  b.width = b.height = b.sourceWidth = b.sourceHeight = 100;
  b.lights = hemisphere81();
  b.views = hemisphere81();
  b.decoder = makeDecoder(8, {106, 106, 106}, rng);
  b.latentRows = 500;
  b.latents.assign(500 * 8, 0.f);
  b.ids.assign(10000, 0);
  return b;
}

TEST(NbtfFile, SizesReproduceThePapersTable1) {
  CompressedBtf b = paperShapedBtf();
  NbtfSizes s = computeSizes(b);
  EXPECT_EQ(s.decoderParameters, 24383u);
  EXPECT_EQ(s.decoder, 97532u);     // 95.2 KiB
  EXPECT_EQ(s.latents, 16000u);     // 15.6 KiB
  EXPECT_EQ(s.idsPaper, 40000u);    // 39.1 KiB with the paper's 4-byte ids
  EXPECT_EQ(s.idWidth, 2);          // k = 500 needs 16 bits
  EXPECT_EQ(s.ids, 20000u);
  EXPECT_EQ(s.total, 97532u + 16000u + 20000u);
  EXPECT_EQ(s.rawFloat32, 787320000u);  // 750.8 MiB, the paper's "751MB"
  EXPECT_NEAR(s.totalPaper / 1024.0, 150, 0.5);
  // The paper prints 1:5127 from its rounded 751 MB / 150 KB; the exact ratio is 5128.05.
  EXPECT_NEAR(s.ratioPaper, 5128.05, 0.01);
  EXPECT_NEAR(s.ratio, 787320000.0 / 133532.0, 1e-9);
  std::string table = formatSizeTable(s);
  EXPECT_TRUE(contains(table, "95.2 KiB")) << table;
  EXPECT_TRUE(contains(table, "15.6 KiB")) << table;
  EXPECT_TRUE(contains(table, "24,383 parameters")) << table;
  EXPECT_TRUE(contains(table, "750.8 MiB")) << table;
  EXPECT_TRUE(contains(table, "1 : 5128.1 (stored the paper's way: float32, 4-byte ids)")) << table;

  // Per-texel (the paper's "neural BTF" column): 313 KB latents, 408 KB total, 1:1885.
  b.method = CodecMethod::PerTexelNeural;
  b.latentRows = 10000;
  b.ids.clear();
  NbtfSizes p = computeSizes(b);
  EXPECT_EQ(p.latents, 320000u);
  EXPECT_EQ(p.ids, 0u);
  EXPECT_NEAR(p.total / 1024.0, 408, 0.5);
  EXPECT_EQ(static_cast<int>(p.ratio), 1885);
}

TEST(NbtfFile, CompactPartsShrinkTheTotalAndAreListed) {
  // The same material with half-precision parts, zstd ids and 8-bit coefficients per texel.
  CompressedBtf b = paperShapedBtf();
  b.latents.assign(500 * 8, 0.25f);
  for (int t = 0; t < 10000; ++t) b.ids[t] = (t % 100) / 10 + 10 * (t / 1000);  // 10 x 10 blocks: coherent
  std::vector<float> coefficients(10000, 1.0f);
  for (int t = 0; t < 10000; ++t) coefficients[t] = 0.5f + (t % 7) * 0.1f;
  b.modulation = quantizeTexelCoefficients(coefficients, 1, 8);
  b.storage.decoderHalf = b.storage.latentsHalf = b.storage.idsZstd = true;
  roundToStorage(b);
  NbtfSizes s = computeSizes(b);
  EXPECT_EQ(s.decoder, 24383u * 2);
  EXPECT_EQ(s.latents, 500u * 8 * 2);
  EXPECT_TRUE(s.idsZstd);
  EXPECT_LT(s.ids, 2000u);  // 20,000 raw bytes of block-coherent ids
  EXPECT_GT(s.modulation, 0u);
  EXPECT_LT(s.modulation, 10000u);  // 8-bit codes with 7 distinct values compress
  EXPECT_EQ(s.total, s.decoder + s.latents + s.ids + s.modulation);
  // The paper-style total stores the same model in float32 with 4-byte ids.
  EXPECT_EQ(s.totalPaper, 97532u + 16000u + 40000u + s.modulation);
  std::string table = formatSizeTable(s);
  EXPECT_TRUE(contains(table, "x 2 bytes (half)")) << table;
  EXPECT_TRUE(contains(table, "zstd-coded")) << table;
  EXPECT_TRUE(contains(table, "per-texel")) << table;
  EXPECT_TRUE(contains(table, "1 coefficient x 8-bit codes")) << table;
  // The file holds what computeSizes counts, plus headers, directions and metadata.
  std::vector<std::uint8_t> bytes = serializeNbtf(b);
  EXPECT_GT(bytes.size(), s.total);
  EXPECT_LT(bytes.size(), s.total + 4000);
}

}  // namespace
}  // namespace nbtf
