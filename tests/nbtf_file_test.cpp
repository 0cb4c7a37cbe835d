// The .nbtf framing (codec/nbtf_file.cpp): round trips, header, section walk, checksums, versions, golden files.
#include "codec/nbtf_file.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <iterator>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "codec/crc32.h"
#include "codec_fixtures.h"
#include "nbtf_file_fixtures.h"
#include "util/atomic_file.h"
#include "util/error.h"

namespace nbtf {
namespace {
namespace fs = std::filesystem;
using testing::makeBtf;
using testing::makePcaBtf;

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

TEST(NbtfFile, SerializationIsDeterministic) {
  EXPECT_EQ(serializeNbtf(makeBtf(5)), serializeNbtf(makeBtf(5)));
  EXPECT_NE(serializeNbtf(makeBtf(5)), serializeNbtf(makeBtf(5, 4, 3, 8, 8)));
}

// ---- Versions and committed files

TEST(NbtfFile, PaperStyleFilesStayFormat10) {
  // Without compact parts or modulation the writer still writes 1.0, readable by older nbtf.
  std::vector<std::uint8_t> bytes = serializeNbtf(makeBtf(5));
  EXPECT_EQ(bytes[8], 1);
  EXPECT_EQ(bytes[10], 0);
  EXPECT_EQ(findSection(bytes, "DECH"), 0u);
  EXPECT_NE(findSection(bytes, "DECD"), 0u);
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

}  // namespace
}  // namespace nbtf
