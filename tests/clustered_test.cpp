// The clustered neural kind (codec/methods/clustered.cpp): its id list and per-texel modulation checks, and its names.
#include <gtest/gtest.h>

#include "codec/methods/method.h"
#include "codec_fixtures.h"
#include "test_util.h"

namespace nbtf {
namespace {

// A valid one-term modulation of makeBtf's 12 texels: 4-bit codes in [-1, 1].
CompressedBtf modulated() {
  CompressedBtf b = testing::makeBtf(5);
  b.modulation.terms = 1;
  b.modulation.channels = 1;
  b.modulation.bits = 4;
  b.modulation.minimum[0] = -1;
  b.modulation.maximum[0] = 1;
  b.modulation.codes.assign(static_cast<std::size_t>(b.numTexels()), 15);
  return b;
}

void expectInvalid(const CompressedBtf& b, const std::string& part) {
  test::expectErrorContaining([&] { clusteredNeuralMethod().validate(b, "c.nbtf"); }, {"c.nbtf", part});
}

TEST(ClusteredNeural, IdsNeedOneInRangePerTexel) {
  CompressedBtf b = testing::makeBtf(5);
  EXPECT_NO_THROW(clusteredNeuralMethod().validate(b, "c.nbtf"));
  b.ids.pop_back();
  expectInvalid(b, "id list has 11 entries, expected one per texel (12)");
  b = testing::makeBtf(5);
  b.ids[7] = -1;
  expectInvalid(b, "id of texel 7 is -1, outside [0, 5)");
}

TEST(ClusteredNeural, ModulationIsCheckedPartByPart) {
  EXPECT_NO_THROW(clusteredNeuralMethod().validate(modulated(), "c.nbtf"));
  CompressedBtf b = modulated();
  b.modulation.bits = 17;
  expectInvalid(b, "modulation codes have 17 bits, expected 1 to 16");
  b = modulated();
  b.modulation.channels = 2;
  expectInvalid(b, "modulation has 2 channels, expected 1 or 3");
  b = modulated();
  b.modulation.codes.pop_back();
  expectInvalid(b, "modulation holds 11 codes, expected 12 texels x 1");
  b = modulated();
  b.modulation.minimum[0] = 2;  // above the maximum
  expectInvalid(b, "modulation range of term 0 is invalid");
  b = modulated();
  b.modulation.codes[3] = 16;
  expectInvalid(b, "modulation code 16 of texel 3 exceeds 4 bits");
  b = modulated();
  b.modulation.decorrelated = true;  // needs three channels
  expectInvalid(b, "decorrelated modulation codes need 3 channels, the file has 1");
}

TEST(ClusteredNeural, NamesShowKAndTheModulation) {
  const MethodKind& kind = clusteredNeuralMethod();
  EXPECT_EQ(kind.name(), std::string("clustered-neural"));
  EXPECT_EQ(kind.shortName(), std::string("clustered"));
  EXPECT_EQ(kind.code(), CodecMethod::ClusteredNeural);
  const CompressedBtf b = modulated();
  EXPECT_EQ(kind.summary(b), "clustered-neural, k = 5 clusters");
  EXPECT_EQ(kind.label(b), "clustered neural + per-texel modulation (1 term), k = 5");
  CompressedBtf three = b;
  three.modulation.terms = 3;
  three.modulation.channels = 3;
  EXPECT_EQ(kind.label(three), "clustered neural + per-texel modulation (3 terms, per channel), k = 5");
  EXPECT_EQ(kind.sweepParameter(b), 5);
}

}  // namespace
}  // namespace nbtf
