// The section table (codec/nbtf_sections.cpp): each section's encoding, its format version and its reader's checks.
#include "codec/nbtf_file.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "codec_fixtures.h"
#include "nbtf_file_fixtures.h"
#include "util/byte_io.h"
#include "util/directions.h"

namespace nbtf {
namespace {
using testing::makeBtf;
using testing::makeDecoder;

// ---- Id list

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

// ---- Compact metadata, hold-out list and directions (METZ, HOLZ, DIRZ)

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

// ---- Decoder (DEC8) and cluster planes (CPLN)

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

// ---- Material info: direction encodings

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

// ---- Sizes and counts in the sections

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

}  // namespace
}  // namespace nbtf
