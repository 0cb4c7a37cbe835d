#include "codec/nbtf_file.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <random>

#include "util/byte_io.h"
#include "codec/crc32.h"
#include "codec/texel_modulation.h"
#include "codec_fixtures.h"
#include "decoder_fixtures.h"
#include "util/atomic_file.h"
#include "util/error.h"
#include "util/half.h"
#include "test_util.h"

namespace nbtf {
namespace {
namespace fs = std::filesystem;
using testing::makeBtf;
using testing::makeDecoder;
using testing::makePcaBtf;

// A decoder for `terms` modulation terms: makeBtf's, with 3 x terms outputs.
void setTerms(CompressedBtf& b, int terms) {
  DenseLayer& last = b.decoder.layers.back();
  last.out = 3 * terms;
  last.weight.assign(static_cast<std::size_t>(last.in) * last.out, 0.125f);
  last.bias.assign(last.out, -0.5f);
}

// A format-1.2 file: per-texel modulation (3 terms, 6-bit codes), half-precision decoder
// and latents, zstd-coded ids.
CompressedBtf makeCompactBtf(int k = 5, int terms = 3, int bits = 6, int channels = 1) {
  CompressedBtf b = makeBtf(k);
  std::vector<float> coefficients(static_cast<std::size_t>(b.numTexels()) * terms * channels);
  for (std::size_t i = 0; i < coefficients.size(); ++i) coefficients[i] = 0.5f - 0.11f * static_cast<float>(i % 9);
  b.modulation = quantizeTexelCoefficients(coefficients, terms, bits, channels);
  setTerms(b, terms);
  b.storage.decoderHalf = b.storage.latentsHalf = b.storage.idsZstd = true;
  roundToStorage(b);
  return b;
}

// A format-1.11 file: per-channel coefficients in decorrelated codes (two terms).
CompressedBtf makeDecorrelatedBtf() {
  CompressedBtf b = makeBtf(5);
  std::vector<float> coefficients(static_cast<std::size_t>(b.numTexels()) * 6);
  for (std::size_t i = 0; i < coefficients.size(); ++i)
    coefficients[i] = 1.0f + 0.1f * static_cast<float>(i / 6 % 7) * (1 + i % 3) - 0.03f * static_cast<float>(i % 5);
  b.modulation = quantizeTexelCoefficients(coefficients, 2, 6, 3, ModulationCodes::Decorrelated);
  setTerms(b, 2);
  b.storage.idsZstd = true;
  return b;
}

// A format-1.10 file: direction planes, and cluster planes in 8 bits.
CompressedBtf makeClusterPlanes8BitBtf() {
  CompressedBtf b =
      testing::makeDecoderMaterial(5, {37, 21}, 7, 5, 11, DirectionEncoding::StereographicFourier2, 2, 2);
  b.storage.decoderInt8 = b.storage.clusterPlanes8Bit = true;
  roundToStorage(b);
  return b;
}

// The files every damage test runs on: clustered neural, the PCA baseline (whose sections
// have their own size fields and checks), compact 1.2 and 1.4 files (zstd frames, half floats,
// 8-bit decoder), a 1.10 file (direction planes, 8-bit cluster planes) and a 1.11 file
// (decorrelated modulation codes, a zstd frame per column).
std::vector<std::pair<std::string, std::vector<std::uint8_t>>> damageTestFiles() {
  CompressedBtf compactMetadata = makeCompactBtf();  // and an 8-bit decoder
  compactMetadata.storage.metadataZstd = compactMetadata.storage.decoderInt8 = true;
  compactMetadata.storage.directionsZstd = true;
  compactMetadata.storage.decoderHalf = false;
  roundToStorage(compactMetadata);
  return {{"clustered", serializeNbtf(makeBtf(5))},
          {"pca", serializeNbtf(makePcaBtf())},
          {"compact", serializeNbtf(makeCompactBtf())},
          {"compact metadata", serializeNbtf(compactMetadata)},
          {"8-bit cluster planes", serializeNbtf(makeClusterPlanes8BitBtf())},
          {"decorrelated modulation", serializeNbtf(makeDecorrelatedBtf())}};
}

std::string errorOf(const std::vector<std::uint8_t>& bytes, std::size_t size = SIZE_MAX,
                    NbtfParseOptions options = {}) {
  try {
    parseNbtf(bytes.data(), std::min(size, bytes.size()), "mat.nbtf", options);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

// Recomputes the declared size and both CRCs after a test edited the bytes on purpose.
void resealHeader(std::vector<std::uint8_t>& b) {
  ByteWriter w;
  w.bytes() = b;
  w.patchU64(16, b.size());
  w.patchU32(24, crc32(b.data() + 32, b.size() - 32));
  w.patchU32(28, crc32(w.bytes().data(), 28));
  b = w.bytes();
}

void appendSection(std::vector<std::uint8_t>& b, const char* tag, std::uint32_t flags,
                   const std::vector<std::uint8_t>& payload, std::uint64_t declaredSize = UINT64_MAX) {
  ByteWriter w;
  w.raw(tag, 4);
  w.u32(flags);
  w.u64(declaredSize == UINT64_MAX ? payload.size() : declaredSize);
  w.u32(crc32(payload.data(), payload.size()));
  w.u32(0);
  w.raw(payload.data(), payload.size());
  w.zeros((8 - payload.size() % 8) % 8);
  b.insert(b.end(), w.bytes().begin(), w.bytes().end());
  resealHeader(b);
}

// Offset of a section's header in a serialized file.
std::size_t findSection(const std::vector<std::uint8_t>& b, const char* tag) {
  std::size_t pos = 32;
  while (pos + 24 <= b.size()) {
    std::uint64_t size = 0;
    for (int i = 0; i < 8; ++i) size |= std::uint64_t(b[pos + 8 + i]) << (8 * i);
    if (std::memcmp(&b[pos], tag, 4) == 0) return pos;
    pos += 24 + size + (8 - size % 8) % 8;
  }
  return 0;
}

void putU32(std::vector<std::uint8_t>& b, std::size_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) b[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
}

// Rewrites a section's stored CRC after its payload was edited on purpose.
void resealSection(std::vector<std::uint8_t>& b, std::size_t sectionOffset) {
  std::uint64_t size = 0;
  for (int i = 0; i < 8; ++i) size |= std::uint64_t(b[sectionOffset + 8 + i]) << (8 * i);
  putU32(b, sectionOffset + 16, crc32(&b[sectionOffset + 24], size));
  resealHeader(b);
}

// ---- Round trips

TEST(NbtfFile, ClusteredRoundTripIsBitExact) {
  CompressedBtf b = makeBtf(5);
  b.encoderState = {1, 2, 3, 250, 0, 7};
  std::vector<std::uint8_t> bytes = serializeNbtf(b);
  CompressedBtf back = parseNbtf(bytes.data(), bytes.size(), "mem");
  EXPECT_EQ(serializeNbtf(back), bytes);
  // Every field came back (floats compared exactly: the format stores their bits).
  EXPECT_EQ(back.method, CodecMethod::ClusteredNeural);
  EXPECT_EQ(back.width, 4);
  EXPECT_EQ(back.height, 3);
  EXPECT_EQ(back.sourceWidth, 14);
  EXPECT_EQ(back.sourceHeight, 23);
  EXPECT_EQ(back.crop, (Crop{3, 5, 4, 3}));
  EXPECT_EQ(back.layout, Layout::Utia);
  EXPECT_EQ(back.sourceSampleType, SampleType::Half);
  EXPECT_EQ(back.lights, b.lights);
  EXPECT_EQ(back.views, b.views);
  EXPECT_EQ(back.alpha, b.alpha);
  ASSERT_EQ(back.decoder.layers.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(back.decoder.layers[i].weight, b.decoder.layers[i].weight);
    EXPECT_EQ(back.decoder.layers[i].bias, b.decoder.layers[i].bias);
    EXPECT_EQ(back.decoder.layers[i].activation, b.decoder.layers[i].activation);
  }
  EXPECT_EQ(back.latents, b.latents);
  EXPECT_EQ(back.ids, b.ids);
  EXPECT_EQ(back.holdoutImages, b.holdoutImages);
  EXPECT_EQ(back.encoderState, b.encoderState);
  EXPECT_EQ(back.metadataJson, b.metadataJson);
  EXPECT_EQ(back.latentOfTexel(7), back.latents.data() + 2 * 8);  // texel 7 -> cluster 7 % 5
}

TEST(NbtfFile, PerTexelRoundTripThroughDisk) {
  fs::path dir = fs::temp_directory_path() / "nbtf_file_test_pertexel";
  fs::remove_all(dir);
  fs::create_directories(dir);
  CompressedBtf b = makeBtf(0);
  b.crop = Crop{};
  b.sourceWidth = b.width;
  b.sourceHeight = b.height;
  b.holdoutImages.clear();
  std::string path = (dir / "m.nbtf").string();
  std::size_t written = writeNbtf(path, b);
  EXPECT_EQ(fs::file_size(path), written);
  EXPECT_TRUE(hasNbtfMagic(path));
  CompressedBtf back = readNbtf(path);
  EXPECT_EQ(back.method, CodecMethod::PerTexelNeural);
  EXPECT_TRUE(back.ids.empty());
  EXPECT_EQ(back.latentRows, 12);
  EXPECT_EQ(back.latentOfTexel(11), back.latents.data() + 11 * 8);
  EXPECT_EQ(serializeNbtf(back), readFileBytes(path));
  // Nothing but the file itself is left in the folder (no temporary).
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
  fs::remove_all(dir);
}

TEST(NbtfFile, PcaRoundTripIsBitExact) {
  CompressedBtf b = makePcaBtf(3);
  std::vector<std::uint8_t> bytes = serializeNbtf(b);
  CompressedBtf back = parseNbtf(bytes.data(), bytes.size(), "mem");
  EXPECT_EQ(serializeNbtf(back), bytes);
  EXPECT_EQ(back.method, CodecMethod::Pca);
  EXPECT_TRUE(back.isPca());
  EXPECT_EQ(back.pcaComponents(), 3);
  EXPECT_EQ(back.latentRows, 12);
  EXPECT_EQ(back.pcaMean, b.pcaMean);
  EXPECT_EQ(back.pcaBasis, b.pcaBasis);
  EXPECT_EQ(back.latents, b.latents);  // the coefficients
  EXPECT_TRUE(back.decoder.layers.empty());
  EXPECT_TRUE(back.ids.empty());
  EXPECT_EQ(back.holdoutImages, b.holdoutImages);
  EXPECT_EQ(back.crop, b.crop);
  EXPECT_EQ(back.lights, b.lights);
  EXPECT_EQ(back.views, b.views);
  // The PCA sections are there, the neural ones are not; PCA files say format 1.1, neural
  // files keep 1.0 (their bytes did not change).
  for (const char* tag : {"PCAM", "PCAB", "PCAC"}) EXPECT_NE(findSection(bytes, tag), 0u) << tag;
  for (const char* tag : {"DECD", "LATN", "TXID"}) EXPECT_EQ(findSection(bytes, tag), 0u) << tag;
  EXPECT_EQ(back.formatMajor, 1);
  EXPECT_EQ(back.formatMinor, 1);
  std::vector<std::uint8_t> neural = serializeNbtf(makeBtf(5));
  EXPECT_EQ(parseNbtf(neural.data(), neural.size(), "mem").formatMinor, 0);
  // Sizes: mean 6 images x 3 x 4, basis x 3 components, coefficients 12 texels x 3 x 4.
  NbtfSizes s = computeSizes(back);
  EXPECT_TRUE(s.pca);
  EXPECT_EQ(s.pcaMean, 6u * 3 * 4);
  EXPECT_EQ(s.pcaBasis, 6u * 3 * 3 * 4);
  EXPECT_EQ(s.pcaCoefficients, 12u * 3 * 4);
  EXPECT_EQ(s.total, s.pcaMean + s.pcaBasis + s.pcaCoefficients);
  EXPECT_EQ(s.decoder + s.latents + s.ids, 0u);
  EXPECT_EQ(s.rawFloat32, 12u * 6 * 3 * 4);
  EXPECT_DOUBLE_EQ(s.ratio, double(s.rawFloat32) / double(s.total));
  std::string table = formatSizeTable(s);
  for (const char* part : {"mean", "basis", "coefficients", "total", "raw float32", "ratio"})
    EXPECT_TRUE(contains(table, part)) << part << "\n" << table;
  EXPECT_FALSE(contains(table, "decoder")) << table;
}

TEST(NbtfFile, PcaContentIsCheckedByName) {
  const std::vector<std::uint8_t> good = serializeNbtf(makePcaBtf(3));
  // PCAB's component count disagreeing with INFO.
  {
    std::vector<std::uint8_t> b = good;
    std::size_t at = findSection(b, "PCAB");
    putU32(b, at + 24 + 4, 4);
    resealSection(b, at);
    EXPECT_TRUE(contains(errorOf(b), "section 'PCAB' (PCA basis)") && contains(errorOf(b), "4 components disagree"))
        << errorOf(b);
  }
  // 4 billion basis rows, mean values, coefficient rows in a few bytes: refused before allocating.
  for (const char* tag : {"PCAM", "PCAB", "PCAC"}) {
    std::vector<std::uint8_t> b = good;
    std::size_t at = findSection(b, tag);
    putU32(b, at + 24, 0xFFFFFFFF);
    resealSection(b, at);
    std::string e = errorOf(b);
    EXPECT_TRUE(contains(e, std::string("section '") + tag + "'") && contains(e, "the section holds")) << tag << ": " << e;
  }
  // A consistent lie: one image fewer in the mean than the directions say.
  {
    CompressedBtf p = makePcaBtf(3);
    std::vector<std::uint8_t> b = good;
    std::size_t at = findSection(b, "PCAM");
    // Rebuild PCAM with 3 values fewer (payload shrinks by 12 bytes: count + floats).
    ByteWriter w;
    w.u32(static_cast<std::uint32_t>(p.pcaMean.size() - 3));
    for (std::size_t i = 0; i + 3 < p.pcaMean.size(); ++i) w.f32(p.pcaMean[i]);
    std::vector<std::uint8_t> rebuilt(b.begin(), b.begin() + static_cast<std::ptrdiff_t>(at));
    std::uint64_t oldSize = 0;
    for (int i = 0; i < 8; ++i) oldSize |= std::uint64_t(b[at + 8 + i]) << (8 * i);
    std::size_t next = at + 24 + oldSize + (8 - oldSize % 8) % 8;
    appendSection(rebuilt, "PCAM", 1, w.bytes());
    rebuilt.insert(rebuilt.end(), b.begin() + static_cast<std::ptrdiff_t>(next), b.end());
    resealHeader(rebuilt);
    EXPECT_TRUE(contains(errorOf(rebuilt), "PCA mean holds 15 values, expected 3 x 6 images")) << errorOf(rebuilt);
  }
  // A NaN in the basis.
  {
    std::vector<std::uint8_t> b = good;
    std::size_t at = findSection(b, "PCAB");
    putU32(b, at + 24 + 8 + 4, 0x7FC00000);
    resealSection(b, at);
    EXPECT_TRUE(contains(errorOf(b), "PCA basis contains non-finite values")) << errorOf(b);
  }
  // A required PCA part missing, and a neural section in a PCA file.
  {
    std::vector<std::uint8_t> b = good;
    std::size_t at = findSection(b, "PCAC");
    b[at] = 'X';  // renamed: an unknown required section...
    resealSection(b, at);
    EXPECT_TRUE(contains(errorOf(b), "required section 'XCAC' is unknown")) << errorOf(b);
    b[at + 4] = 0;  // ...made optional: skipped, so the coefficients are missing
    resealSection(b, at);
    EXPECT_TRUE(contains(errorOf(b), "missing section 'PCAC' (PCA coefficients) (required by the PCA method)"))
        << errorOf(b);
    std::vector<std::uint8_t> extra = good;
    ByteWriter latents;  // well-formed latents of the right shape (12 rows x 3)
    latents.u32(12);
    latents.u32(3);
    for (int i = 0; i < 36; ++i) latents.f32(0);
    appendSection(extra, "LATN", 1, latents.bytes());
    EXPECT_TRUE(contains(errorOf(extra), "section 'LATN' (latents) present, but the method is pca")) << errorOf(extra);
  }
  // More components than min(texels, 3 x images) allows: the writer refuses.
  {
    CompressedBtf p = makePcaBtf(13);  // 12 texels
    EXPECT_THROW(serializeNbtf(p), Error);
    try {
      serializeNbtf(p);
    } catch (const Error& e) {
      EXPECT_TRUE(contains(e.what(), "13 PCA components, expected 1 to 12")) << e.what();
    }
  }
}

TEST(NbtfFile, SerializationIsDeterministic) {
  EXPECT_EQ(serializeNbtf(makeBtf(5)), serializeNbtf(makeBtf(5)));
  EXPECT_NE(serializeNbtf(makeBtf(5)), serializeNbtf(makeBtf(5, 4, 3, 8, 8)));
}

// ---- Id widths

TEST(NbtfFile, IdWidthIsTheSmallestThatFitsK) {
  EXPECT_EQ(idWidthForClusters(1), 1);
  EXPECT_EQ(idWidthForClusters(255), 1);
  EXPECT_EQ(idWidthForClusters(256), 1);  // ids 0..255
  EXPECT_EQ(idWidthForClusters(257), 2);
  EXPECT_EQ(idWidthForClusters(65536), 2);  // ids 0..65535
  EXPECT_EQ(idWidthForClusters(65537), 4);
}

TEST(NbtfFile, LargestIdSurvivesAtEachWidthBoundary) {
  for (int k : {255, 256, 257, 65536, 65537}) {
    CompressedBtf b = makeBtf(3, 4, 3, /*latentDim=*/1);
    b.latentRows = k;
    b.latents.assign(static_cast<std::size_t>(k), 0.5f);
    b.ids[0] = k - 1;
    b.ids[11] = k - 2;
    std::vector<std::uint8_t> bytes = serializeNbtf(b);
    CompressedBtf back = parseNbtf(bytes.data(), bytes.size(), "mem");
    EXPECT_EQ(back.ids, b.ids) << "k = " << k;
    NbtfSizes s = computeSizes(back);
    EXPECT_EQ(s.idWidth, idWidthForClusters(k));
    EXPECT_EQ(s.ids, 12u * s.idWidth);
    // The id section really is that wide: 8 bytes of count/width + 12 ids, padded to 8.
    std::size_t at = findSection(bytes, "TXID");
    ASSERT_NE(at, 0u);
    EXPECT_EQ(bytes[at + 8], 8 + 12 * s.idWidth) << "k = " << k;
  }
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

// storage.metadata and storage.directions "zstd" (format 1.4): the metadata JSON, the hold-out
// list (as a bit mask over the images) and the directions (byte planes of their f64 values)
// are zstd frames, METZ, HOLZ and DIRZ; they read back to the same values, bit for bit.
TEST(NbtfFile, CompactMetadataRoundTripsAndIsSmaller) {
  CompressedBtf b = makeBtf(5, 4, 3);
  b.lights.assign(9, Direction{10, 0});
  b.views.assign(9, Direction{20, 0});
  for (std::size_t i = 0; i < b.lights.size(); ++i) b.lights[i].phiDeg = b.views[i].phiDeg = 40.0 * i;
  b.lights[3].thetaDeg = 17.123456789012345;  // an irregular angle (UTIA's shifted lights) stays exact
  b.holdoutImages = {0, 7, 8, 9, 40, 80};  // first and last of 81 images, a byte boundary
  std::string json = R"({"source": {"path": "/data/captures/fabric"}, "config": {"epochs": 20}, "fingerprint": [)";
  for (int i = 0; i < 200; ++i) json += (i ? ", " : "") + std::to_string(0.25 + 0.001 * i);
  b.metadataJson = json + "]}";
  const std::vector<std::uint8_t> raw = serializeNbtf(b);
  b.storage.metadataZstd = b.storage.directionsZstd = true;
  const std::vector<std::uint8_t> bytes = serializeNbtf(b);
  EXPECT_EQ(bytes[10], 4);  // format 1.4
  EXPECT_EQ(raw[10], 0);    // the same material stored raw stays 1.0
  for (const char* tag : {"METZ", "HOLZ", "DIRZ"}) EXPECT_NE(findSection(bytes, tag), 0u) << tag;
  for (const char* tag : {"META", "HOLD", "DIRS"}) EXPECT_EQ(findSection(bytes, tag), 0u) << tag;
  EXPECT_LT(bytes.size() + 500, raw.size()) << "compact " << bytes.size() << " B, raw " << raw.size() << " B";
  CompressedBtf back = parseNbtf(bytes.data(), bytes.size(), "mem");
  EXPECT_EQ(back.formatMinor, 4);
  EXPECT_TRUE(back.storage.metadataZstd && back.storage.directionsZstd);
  for (std::size_t i = 0; i < b.lights.size(); ++i) {
    EXPECT_EQ(back.lights[i].thetaDeg, b.lights[i].thetaDeg);
    EXPECT_EQ(back.lights[i].phiDeg, b.lights[i].phiDeg);
    EXPECT_EQ(back.views[i].phiDeg, b.views[i].phiDeg);
  }
  EXPECT_EQ(back.metadataJson, b.metadataJson);
  EXPECT_EQ(back.holdoutImages, b.holdoutImages);
  EXPECT_EQ(serializeNbtf(back), bytes);
  // No hold-out images: no HOLZ section, and the file still reads.
  b.holdoutImages.clear();
  const std::vector<std::uint8_t> none = serializeNbtf(b);
  EXPECT_EQ(findSection(none, "HOLZ"), 0u);
  EXPECT_TRUE(parseNbtf(none.data(), none.size(), "mem").holdoutImages.empty());
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

TEST(NbtfFile, Int8DecoderContentIsCheckedByName) {
  CompressedBtf b = makeBtf(5);
  b.storage.decoderInt8 = true;
  roundToStorage(b);
  const std::vector<std::uint8_t> bytes = serializeNbtf(b);
  const std::size_t at = findSection(bytes, "DEC8");
  ASSERT_NE(at, 0u);
  // Layer 0 (12 inputs, 6 outputs): header at payload + 4, scales at + 16, codes at + 28.
  const std::size_t scales = at + 24 + 4 + 12, codes = scales + 2 * 6;
  auto errorWith = [&](std::size_t offset, std::uint8_t value) {
    std::vector<std::uint8_t> bad = bytes;
    bad[offset] = value;
    resealSection(bad, at);
    return errorOf(bad);
  };
  EXPECT_TRUE(contains(errorWith(codes + 3, 0x80), "layer 0 row 0: code -128")) << errorWith(codes + 3, 0x80);
  // Every code of row 0 made small: the scale no longer fits the row.
  {
    std::vector<std::uint8_t> bad = bytes;
    for (int i = 0; i < 12; ++i) bad[codes + i] = 1;
    resealSection(bad, at);
    EXPECT_TRUE(contains(errorOf(bad), "layer 0 row 0: largest code 1, expected 127")) << errorOf(bad);
  }
  // A scale of infinity (half 0x7C00).
  {
    std::vector<std::uint8_t> bad = bytes;
    bad[scales] = 0x00;
    bad[scales + 1] = 0x7C;
    resealSection(bad, at);
    EXPECT_TRUE(contains(errorOf(bad), "is not a finite half value")) << errorOf(bad);
  }
  // Two encodings of the decoder.
  std::vector<std::uint8_t> two = serializeNbtf(makeCompactBtf());
  const std::size_t half = findSection(two, "DECH");
  std::uint64_t size = 0;
  for (int i = 0; i < 8; ++i) size |= std::uint64_t(bytes[at + 8 + i]) << (8 * i);
  appendSection(two, "DEC8", 1, std::vector<std::uint8_t>(bytes.begin() + at + 24, bytes.begin() + at + 24 + size));
  EXPECT_TRUE(contains(errorOf(two), "both section 'DECH'")) << errorOf(two);
  EXPECT_NE(half, 0u);
}

// The compact sections' own fields are checked against the material, by name.
TEST(NbtfFile, CompactMetadataContentIsCheckedByName) {
  CompressedBtf b = makeCompactBtf();
  b.storage.metadataZstd = b.storage.directionsZstd = true;
  const std::vector<std::uint8_t> bytes = serializeNbtf(b);
  const std::size_t hol = findSection(bytes, "HOLZ");
  ASSERT_NE(hol, 0u);
  {
    std::vector<std::uint8_t> bad = bytes;
    putU32(bad, hol + 24, 3);  // the mask holds 2 images
    resealSection(bad, hol);
    EXPECT_TRUE(contains(errorOf(bad), "the mask holds 2 images, the section says 3")) << errorOf(bad);
  }
  {
    std::vector<std::uint8_t> bad = bytes;
    putU32(bad, hol + 28, 7);  // 6 images in the material
    resealSection(bad, hol);
    EXPECT_TRUE(contains(errorOf(bad), "a mask of 7 images, the material has 6")) << errorOf(bad);
  }
  const std::size_t dirs = findSection(bytes, "DIRZ");
  ASSERT_NE(dirs, 0u);
  {
    std::vector<std::uint8_t> bad = bytes;
    putU32(bad, dirs + 24, 4);  // 3 lights in the frame
    resealSection(bad, dirs);
    const std::string e = errorOf(bad);
    EXPECT_TRUE(contains(e, "section 'DIRZ' (directions, zstd-coded)")) << e;
  }
  {
    std::vector<std::uint8_t> bad = bytes;
    putU32(bad, dirs + 28, 0x7FFFFFFFu);
    resealSection(bad, dirs);
    EXPECT_TRUE(contains(errorOf(bad), "at most 1048576 each")) << errorOf(bad);
  }
  const std::size_t meta = findSection(bytes, "METZ");
  ASSERT_NE(meta, 0u);
  {
    std::vector<std::uint8_t> bad = bytes;
    putU32(bad, meta + 24, 5);  // not the frame's size
    resealSection(bad, meta);
    const std::string e = errorOf(bad);
    EXPECT_TRUE(contains(e, "mat.nbtf") && contains(e, "section 'METZ' (metadata, zstd-coded)")) << e;
  }
  {
    std::vector<std::uint8_t> bad = bytes;
    putU32(bad, meta + 24, 0xFFFFFFFFu);
    resealSection(bad, meta);
    EXPECT_TRUE(contains(errorOf(bad), "more than the 67108864 allowed")) << errorOf(bad);
  }
  // Both encodings of the metadata in one file.
  std::vector<std::uint8_t> two = bytes;
  const std::string text = "{}";
  appendSection(two, "META", 0, std::vector<std::uint8_t>(text.begin(), text.end()));
  EXPECT_TRUE(contains(errorOf(two), "both section 'META'")) << errorOf(two);
}

TEST(NbtfFile, PaperStyleFilesStayFormat10) {
  // Without compact parts or modulation the writer still writes 1.0, readable by older nbtf.
  std::vector<std::uint8_t> bytes = serializeNbtf(makeBtf(5));
  EXPECT_EQ(bytes[8], 1);
  EXPECT_EQ(bytes[10], 0);
  EXPECT_EQ(findSection(bytes, "DECH"), 0u);
  EXPECT_NE(findSection(bytes, "DECD"), 0u);
}

// A decoder with the half-vector direction inputs is format 1.3: the encoding byte of INFO
// says how many inputs follow the latent, and a reader checks the first layer against it.
TEST(NbtfFile, HalfVectorDirectionInputsAreFormat13AndChecked) {
  CompressedBtf b = makeBtf(5);
  std::mt19937 rng(4);
  b.directionEncoding = DirectionEncoding::StereographicHalf;
  b.decoder = makeDecoder(b.latentDim, {6, 5}, rng, 8);
  std::vector<std::uint8_t> bytes = serializeNbtf(b);
  EXPECT_EQ(bytes[10], 3);  // format 1.3
  CompressedBtf back = parseNbtf(bytes.data(), bytes.size(), "mem");
  EXPECT_EQ(back.directionEncoding, DirectionEncoding::StereographicHalf);
  EXPECT_EQ(back.decoder.layers[0].in, b.latentDim + 8);
  EXPECT_EQ(serializeNbtf(back), bytes);
  // The same decoder labelled with the paper's encoding: the first layer does not fit.
  {
    std::vector<std::uint8_t> bad = bytes;
    std::size_t at = findSection(bad, "INFO");
    bad[at + 24 + 1] = 1;
    resealSection(bad, at);
    EXPECT_TRUE(contains(errorOf(bad), "takes 16 inputs, expected 12 (latent + 4 direction inputs, stereographic)"))
        << errorOf(bad);
  }
  // An encoding this build does not know.
  {
    std::vector<std::uint8_t> bad = bytes;
    std::size_t at = findSection(bad, "INFO");
    bad[at + 24 + 1] = 9;
    resealSection(bad, at);
    EXPECT_TRUE(contains(errorOf(bad), "unknown direction encoding code 9")) << errorOf(bad);
  }
}

// The Fourier direction inputs are format 1.6 with 3 octaves (a 1.5 reader refuses encoding 3
// by name) and 1.7 with 2 (encoding 4), and the reader checks the first layer's width against them.
TEST(NbtfFile, FourierDirectionInputsAreFormat16Or17AndChecked) {
  for (auto [encoding, minor] : {std::pair{DirectionEncoding::StereographicFourier, 6},
                                 std::pair{DirectionEncoding::StereographicFourier2, 7}}) {
    CompressedBtf b = makeBtf(5);
    std::mt19937 rng(4);
    const int inputs = directionInputCount(encoding);
    b.directionEncoding = encoding;
    b.decoder = makeDecoder(b.latentDim, {6, 5}, rng, inputs);
    std::vector<std::uint8_t> bytes = serializeNbtf(b);
    EXPECT_EQ(bytes[10], minor);  // format 1.6 / 1.7
    CompressedBtf back = parseNbtf(bytes.data(), bytes.size(), "mem");
    EXPECT_EQ(back.directionEncoding, encoding);
    EXPECT_EQ(back.decoder.layers[0].in, b.latentDim + inputs);
    EXPECT_EQ(serializeNbtf(back), bytes);
    std::vector<std::uint8_t> bad = bytes;
    std::size_t at = findSection(bad, "INFO");
    bad[at + 24 + 1] = 2;
    resealSection(bad, at);
    EXPECT_TRUE(contains(errorOf(bad), "expected 16 (latent + 8 direction inputs, stereographic+half)")) << errorOf(bad);
    // The two Fourier encodings differ in width, so one cannot pass for the other.
    bad = bytes;
    bad[at + 24 + 1] = encoding == DirectionEncoding::StereographicFourier ? 4 : 3;
    resealSection(bad, at);
    EXPECT_TRUE(contains(errorOf(bad), encoding == DirectionEncoding::StereographicFourier ? "20 direction inputs"
                                                                                          : "28 direction inputs"))
        << errorOf(bad);
  }
}

// A file written by nbtf before format 1.2 (tests/data/legacy_v1_0.nbtf, made by the
// commit before it with `nbtf compress`) still reads, and decodes to the values it held.
TEST(NbtfFile, CommittedFormat10FileStillReads) {
  const std::string path = std::string(NBTF_SOURCE_DIR) + "/tests/data/legacy_v1_0.nbtf";
  CompressedBtf b = readNbtf(path);
  EXPECT_EQ(b.formatMajor, 1);
  EXPECT_EQ(b.formatMinor, 0);
  EXPECT_EQ(b.method, CodecMethod::ClusteredNeural);
  EXPECT_TRUE(b.modulation.empty());
  EXPECT_FALSE(b.storage.decoderHalf || b.storage.latentsHalf || b.storage.idsZstd);
  // Re-serialized, it is the same bytes: this build writes 1.0 files exactly as before.
  EXPECT_EQ(serializeNbtf(b), readFileBytes(path));
}

// Every committed file, of every format version (tests/data, and the fuzz corpus's valid
// seeds), reads and re-serializes to the same bytes: the writer derives each file's version
// from its sections, and writes each section as the version that introduced it did.
TEST(NbtfFile, EveryCommittedFileReserializesToItsBytes) {
  std::vector<std::string> paths;
  for (const char* dir : {"/tests/data", "/fuzz/corpus"})
    for (const auto& entry : std::filesystem::directory_iterator(std::string(NBTF_SOURCE_DIR) + dir))
      if (entry.path().extension() == ".nbtf") paths.push_back(entry.path().string());
  std::sort(paths.begin(), paths.end());
  std::vector<int> minors;
  for (const std::string& path : paths) {
    const CompressedBtf b = readNbtf(path);
    EXPECT_EQ(serializeNbtf(b), readFileBytes(path)) << path;
    minors.push_back(b.formatMinor);
  }
  std::sort(minors.begin(), minors.end());
  minors.erase(std::unique(minors.begin(), minors.end()), minors.end());
  EXPECT_EQ(minors, (std::vector<int>{0, 1, 2, 4, 5, 6, 7, 8, 9, 10, 11}));
}

TEST(NbtfFile, CompactContentIsCheckedByName) {
  {
    CompressedBtf b = makeCompactBtf();
    b.decoder.layers[0].weight[0] = 0.1f;  // not a half value
    test::expectErrorContaining([&] { serializeNbtf(b); }, {"half precision", "cannot represent"});
  }
  {
    CompressedBtf b = makeCompactBtf();
    b.modulation.codes[3] = 64;  // 6-bit codes
    test::expectErrorContaining([&] { serializeNbtf(b); }, {"modulation code 64", "exceeds 6 bits"});
  }
  {
    CompressedBtf b = makeDecorrelatedBtf();
    b.modulation.rotation[9 + 4] = 1.5f;  // term 1's second axis
    test::expectErrorContaining([&] { serializeNbtf(b); }, {"modulation rotation of term 1", "not orthonormal"});
    // A damaged rotation in a file is refused by name too.
    std::vector<std::uint8_t> bytes = serializeNbtf(makeDecorrelatedBtf());
    const std::size_t at = findSection(bytes, "TXCR");
    const std::size_t rotation = at + 24 + 8 + 6 * 8;  // header, fixed fields, six ranges
    putU32(bytes, rotation, 0x40000000u);  // 2.0f
    resealSection(bytes, at);
    EXPECT_TRUE(contains(errorOf(bytes), "not orthonormal")) << errorOf(bytes);
  }
  {
    CompressedBtf b = makeCompactBtf();
    b.modulation.decorrelated = true;  // one channel
    test::expectErrorContaining([&] { serializeNbtf(b); }, {"decorrelated modulation codes need 3 channels"});
  }
  {
    CompressedBtf b = makeCompactBtf();
    b.modulation.codes.pop_back();
    test::expectErrorContaining([&] { serializeNbtf(b); }, {"modulation holds"});
  }
  {
    CompressedBtf b = makeCompactBtf();
    b.modulation.maximum[1] = NAN;
    test::expectErrorContaining([&] { serializeNbtf(b); }, {"modulation range of term 1"});
  }
  {
    CompressedBtf b = makeCompactBtf();
    setTerms(b, 2);  // 3 terms of coefficients, 2 of decoder outputs
    roundToStorage(b);
    test::expectErrorContaining([&] { serializeNbtf(b); }, {"decoder outputs 6 values, expected 9"});
  }
  {
    CompressedBtf b = makeBtf(0);  // per-texel
    b.modulation = quantizeTexelCoefficients(std::vector<float>(12, 1.0f), 1, 8);
    test::expectErrorContaining([&] { serializeNbtf(b); }, {"only defined for the clustered method"});
  }
  // Two encodings of one part in one file.
  std::vector<std::uint8_t> bytes = serializeNbtf(makeCompactBtf());
  std::size_t at = findSection(bytes, "LATH");
  ASSERT_NE(at, 0u);
  std::vector<std::uint8_t> payload(bytes.begin() + at + 24, bytes.begin() + at + 24 + 8 + 5 * 8 * 4);
  putU32(payload, 0, 5);
  putU32(payload, 4, 8);
  appendSection(bytes, "LATN", 1, payload);
  EXPECT_TRUE(contains(errorOf(bytes), "both section 'LATN'")) << errorOf(bytes);
}

// ---- Rejected files

TEST(NbtfFile, EveryTruncationIsRejectedAsTruncated) {
  for (const auto& [kind, bytes] : damageTestFiles()) {
    for (std::size_t n = 0; n < bytes.size(); ++n) {
      std::string e = errorOf(bytes, n);
      ASSERT_TRUE(contains(e, "mat.nbtf: ") && contains(e, "truncated")) << kind << " prefix " << n << ": " << e;
    }
    EXPECT_EQ(errorOf(bytes), "") << kind;
  }
}

TEST(NbtfFile, TruncationIsCaughtStructurallyWithoutChecksums) {
  // The fuzzer's mode: with the declared size made to match and no CRCs, the section walk
  // itself must catch every cut, except one that removes whole optional trailing sections.
  for (const auto& [kind, bytes] : damageTestFiles()) {
    std::vector<std::size_t> boundaries;
    for (const char* tag : {"HOLD", "META", "HOLZ", "METZ"}) boundaries.push_back(findSection(bytes, tag));
    NbtfParseOptions noCrc;
    noCrc.verifyChecksums = false;
    for (std::size_t n = 32; n < bytes.size(); ++n) {
      std::vector<std::uint8_t> cut(bytes.begin(), bytes.begin() + n);
      resealHeader(cut);
      bool isBoundary = std::find(boundaries.begin(), boundaries.end(), n) != boundaries.end();
      ASSERT_EQ(errorOf(cut, SIZE_MAX, noCrc).empty(), isBoundary)
          << kind << " prefix " << n << ": " << errorOf(cut, SIZE_MAX, noCrc);
    }
  }
}

TEST(NbtfFile, EveryFlippedByteIsRejected) {
  for (const auto& [kind, bytes] : damageTestFiles()) {
    for (std::size_t i = 0; i < bytes.size(); ++i) {
      for (std::uint8_t mask : {0x01, 0x80}) {
        std::vector<std::uint8_t> bad = bytes;
        bad[i] ^= mask;
        std::string e = errorOf(bad);
        if (i < 8)
          ASSERT_TRUE(contains(e, "not an .nbtf file")) << kind << " " << i << ": " << e;
        else if (i < 32)
          ASSERT_TRUE(contains(e, "header checksum mismatch")) << kind << " " << i << ": " << e;
        else
          ASSERT_TRUE(contains(e, "corrupted: checksum mismatch")) << kind << " " << i << ": " << e;
      }
    }
  }
}

// CPLN value type 2 (format 1.10): an unknown type and a range that is not lo <= hi are
// refused by name.
TEST(NbtfFile, EightBitClusterPlaneRangesAndTypeAreChecked) {
  const std::vector<std::uint8_t> good = serializeNbtf(makeClusterPlanes8BitBtf());
  EXPECT_EQ(good[10], 10);
  const std::size_t at = findSection(good, "CPLN");
  ASSERT_NE(at, 0u);
  EXPECT_EQ(good[at + 24 + 12], 2);
  {
    std::vector<std::uint8_t> b = good;
    b[at + 24 + 12] = 3;
    resealSection(b, at);
    EXPECT_TRUE(contains(errorOf(b), "unknown cluster plane value type 3")) << errorOf(b);
  }
  {
    std::vector<std::uint8_t> b = good;
    // Row 1, feature 0: hi below lo.
    const std::size_t hi = at + 24 + 16 + (1 * 2 + 0) * 8 + 4;
    ByteWriter w;
    w.f32(-1e6f);
    std::copy(w.bytes().begin(), w.bytes().end(), b.begin() + hi);
    resealSection(b, at);
    const std::string e = errorOf(b);
    EXPECT_TRUE(contains(e, "section 'CPLN'") && contains(e, "cluster plane range 2 (row 1, feature 0)")) << e;
  }
}

TEST(NbtfFile, ChecksumErrorNamesTheDamagedSection) {
  std::vector<std::uint8_t> bytes = serializeNbtf(makeBtf(5));
  std::size_t at = findSection(bytes, "LATN");
  ASSERT_NE(at, 0u);
  bytes[at + 24 + 20] ^= 0x10;
  EXPECT_TRUE(contains(errorOf(bytes), "damaged: section 'LATN' (latents)")) << errorOf(bytes);
}

TEST(NbtfFile, WrongMagicIsRejected) {
  std::vector<std::uint8_t> png = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A, 0, 0, 0, 0};
  EXPECT_TRUE(contains(errorOf(png), "mat.nbtf: not an .nbtf file"));
  std::string text = "{\"epochs\": 3}\n";
  EXPECT_TRUE(contains(errorOf(std::vector<std::uint8_t>(text.begin(), text.end())), "not an .nbtf file"));
}

TEST(NbtfFile, NewerMajorVersionIsRefusedNewerMinorIsRead) {
  std::vector<std::uint8_t> bytes = serializeNbtf(makeBtf(5));
  std::vector<std::uint8_t> major = bytes;
  major[8] = 2;
  resealHeader(major);
  std::string e = errorOf(major);
  EXPECT_TRUE(contains(e, "format version 2.0 is newer than this nbtf can read")) << e;
  std::vector<std::uint8_t> minor = bytes;
  minor[10] = 9;
  resealHeader(minor);
  EXPECT_EQ(errorOf(minor), "");
  std::vector<std::uint8_t> zero = bytes;
  zero[8] = 0;
  resealHeader(zero);
  EXPECT_TRUE(contains(errorOf(zero), "invalid format version 0.0"));
}

TEST(NbtfFile, UnknownSectionsOptionalSkippedRequiredRefused) {
  std::vector<std::uint8_t> bytes = serializeNbtf(makeBtf(5));
  std::vector<std::uint8_t> optional = bytes;
  appendSection(optional, "XTRA", 0, {1, 2, 3});
  CompressedBtf b = parseNbtf(optional.data(), optional.size(), "mem");
  EXPECT_EQ(b.skippedSections, std::vector<std::string>{"XTRA"});
  std::vector<std::uint8_t> required = bytes;
  appendSection(required, "XTRA", 1, {1, 2, 3});
  EXPECT_TRUE(contains(errorOf(required), "required section 'XTRA' is unknown to this nbtf")) << errorOf(required);
  std::vector<std::uint8_t> twice = bytes;
  appendSection(twice, "HOLD", 0, {0, 0, 0, 0});
  EXPECT_TRUE(contains(errorOf(twice), "appears twice")) << errorOf(twice);
  std::vector<std::uint8_t> trailing = bytes;
  trailing.push_back(0);
  EXPECT_TRUE(contains(errorOf(trailing), "1 unexpected bytes after the end")) << errorOf(trailing);
}

TEST(NbtfFile, AbsurdSizesAreRejectedWithoutAllocating) {
  const std::vector<std::uint8_t> good = serializeNbtf(makeBtf(5));
  // A section declaring 2^63 bytes.
  {
    std::vector<std::uint8_t> b = good;
    appendSection(b, "XTRA", 0, {}, 1ull << 63);
    EXPECT_TRUE(contains(errorOf(b), "declares 9223372036854775808 bytes")) << errorOf(b);
  }
  // Latent rows 2^31-1 in both INFO and LATN (the checksums are valid: the lie is consistent).
  {
    std::vector<std::uint8_t> b = good;
    std::size_t info = findSection(b, "INFO"), latn = findSection(b, "LATN");
    putU32(b, info + 24 + 48, 0x7FFFFFFF);
    resealSection(b, info);
    putU32(b, latn + 24, 0x7FFFFFFF);
    resealSection(b, latn);
    EXPECT_TRUE(contains(errorOf(b), "expected 68719476704")) << errorOf(b);
  }
  // A decoder layer of 65536 x 65536 (16 GiB of weights) in a few bytes.
  {
    std::vector<std::uint8_t> b = good;
    std::size_t decd = findSection(b, "DECD");
    putU32(b, decd + 24 + 4, 65536);
    putU32(b, decd + 24 + 8, 65536);
    resealSection(b, decd);
    EXPECT_TRUE(contains(errorOf(b), "layer weights declares 4294967296 items")) << errorOf(b);
  }
  // 4 billion directions, 4 billion ids, 4 billion hold-out indices.
  for (const char* tag : {"DIRS", "TXID", "HOLD"}) {
    std::vector<std::uint8_t> b = good;
    std::size_t at = findSection(b, tag);
    putU32(b, at + 24, 0xFFFFFFFF);
    resealSection(b, at);
    std::string e = errorOf(b);
    EXPECT_TRUE(contains(e, std::string("section '") + tag + "'") && contains(e, "42949672")) << tag << ": " << e;
  }
  // Texel size beyond the limit.
  {
    std::vector<std::uint8_t> b = good;
    std::size_t info = findSection(b, "INFO");
    putU32(b, info + 24 + 8, 0xFFFFFFFF);
    resealSection(b, info);
    EXPECT_TRUE(contains(errorOf(b), "width = 4294967295 exceeds the limit")) << errorOf(b);
  }
}

TEST(NbtfFile, InconsistentContentIsRejectedByName) {
  const std::vector<std::uint8_t> good = serializeNbtf(makeBtf(5));
  // An id pointing past the last cluster.
  {
    std::vector<std::uint8_t> b = good;
    std::size_t at = findSection(b, "TXID");
    b[at + 24 + 8 + 3] = 5;
    resealSection(b, at);
    EXPECT_TRUE(contains(errorOf(b), "id of texel 3 is 5, outside [0, 5)")) << errorOf(b);
  }
  // A NaN latent.
  {
    std::vector<std::uint8_t> b = good;
    std::size_t at = findSection(b, "LATN");
    putU32(b, at + 24 + 8, 0x7FC00000);
    resealSection(b, at);
    EXPECT_TRUE(contains(errorOf(b), "latents contain non-finite values")) << errorOf(b);
  }
  // A light below the horizon (theta = 120 degrees).
  {
    std::vector<std::uint8_t> b = good;
    std::size_t at = findSection(b, "DIRS");
    double theta = 120;
    std::memcpy(&b[at + 24 + 8], &theta, 8);
    resealSection(b, at);
    EXPECT_TRUE(contains(errorOf(b), "light 0 direction theta = 120")) << errorOf(b);
  }
  // A neural file relabelled as PCA: its decoder section does not belong to the method.
  {
    std::vector<std::uint8_t> b = good;
    std::size_t at = findSection(b, "INFO");
    b[at + 24] = 3;
    resealSection(b, at);
    EXPECT_TRUE(contains(errorOf(b), "present, but the method is pca")) << errorOf(b);
  }
}

TEST(NbtfFile, RandomMutationsNeverCrash) {
  // A small in-suite fuzz pass (scripts/fuzz.sh runs the real one): every mutated file is
  // either read or rejected with an nbtf::Error; under ASan this also proves no bad access.
  for (const auto& [kind, good] : damageTestFiles()) {
  std::mt19937 rng(123);
  NbtfParseOptions noCrc;
  noCrc.verifyChecksums = false;
  int accepted = 0;
  for (int iter = 0; iter < 3000; ++iter) {
    std::vector<std::uint8_t> b = good;
    int edits = 1 + static_cast<int>(rng() % 4);
    for (int e = 0; e < edits; ++e) {
      std::size_t at = rng() % b.size();
      switch (rng() % 3) {
        case 0: b[at] = static_cast<std::uint8_t>(rng()); break;
        case 1: b[at] = 0xFF; break;
        default: b.resize(at); break;
      }
      if (b.empty()) break;
    }
    try {
      parseNbtf(b.data(), b.size(), "fuzz", noCrc);
      ++accepted;
    } catch (const Error&) {
    }
  }
  EXPECT_LT(accepted, 3000) << kind;
  }
}

TEST(NbtfFile, WriterRefusesInvalidContentAndLeavesNoFile) {
  fs::path dir = fs::temp_directory_path() / "nbtf_file_test_invalid";
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::string path = (dir / "bad.nbtf").string();
  CompressedBtf nan = makeBtf(5);
  nan.decoder.layers[1].weight[3] = std::nanf("");
  try {
    writeNbtf(path, nan);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_TRUE(contains(e.what(), "bad.nbtf: refusing to write")) << e.what();
    EXPECT_TRUE(contains(e.what(), "decoder layer 1 has non-finite parameters")) << e.what();
  }
  CompressedBtf json = makeBtf(5);
  json.metadataJson = "{\"a\": ";
  EXPECT_THROW(writeNbtf(path, json), Error);
  json.metadataJson = std::string(100, '[') + std::string(100, ']');
  EXPECT_THROW(writeNbtf(path, json), Error);
  CompressedBtf shape = makeBtf(5);
  shape.decoder.layers[0].in = 11;
  EXPECT_THROW(writeNbtf(path, shape), Error);
  EXPECT_TRUE(fs::is_empty(dir));
  fs::remove_all(dir);
}

TEST(NbtfFile, MissingFileAndNonNbtfPathsAreNamed) {
  try {
    readNbtf("/nonexistent/x.nbtf");
    FAIL();
  } catch (const Error& e) {
    EXPECT_TRUE(contains(e.what(), "/nonexistent/x.nbtf")) << e.what();
  }
  EXPECT_FALSE(hasNbtfMagic("/nonexistent/x.nbtf"));
  EXPECT_FALSE(hasNbtfMagic(fs::temp_directory_path().string()));
}

TEST(Crc32, MatchesTheStandardCheckValue) {
  const char* check = "123456789";
  EXPECT_EQ(crc32(check, 9), 0xCBF43926u);  // the CRC-32/ISO-HDLC check value
  EXPECT_EQ(crc32(crc32(check, 4), check + 4, 5), 0xCBF43926u);
  EXPECT_EQ(crc32("", 0), 0u);
}

}  // namespace
}  // namespace nbtf
