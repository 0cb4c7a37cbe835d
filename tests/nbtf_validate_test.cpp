// CompressedBtf::validate (codec/nbtf_validate.cpp): invalid content is refused by name, on writing and reading.
#include "codec/nbtf_file.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "codec/texel_modulation.h"
#include "codec_fixtures.h"
#include "nbtf_file_fixtures.h"
#include "test_util.h"
#include "util/byte_io.h"
#include "util/error.h"

namespace nbtf {
namespace {
namespace fs = std::filesystem;
using testing::makeBtf;
using testing::makePcaBtf;

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

}  // namespace
}  // namespace nbtf
