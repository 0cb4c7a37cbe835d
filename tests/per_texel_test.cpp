// The per-texel neural kind (codec/methods/per_texel.cpp): one latent per texel, no ids or modulation, and its names.
#include <gtest/gtest.h>

#include "codec/methods/method.h"
#include "codec_fixtures.h"
#include "test_util.h"

namespace nbtf {
namespace {

void expectInvalid(const CompressedBtf& b, const std::string& part) {
  test::expectErrorContaining([&] { perTexelNeuralMethod().validate(b, "p.nbtf"); }, {"p.nbtf", part});
}

TEST(PerTexelNeural, OneLatentPerTexelAndNoIdsOrModulation) {
  CompressedBtf b = testing::makeBtf(0);
  EXPECT_NO_THROW(perTexelNeuralMethod().validate(b, "p.nbtf"));
  b.ids.assign(12, 0);
  expectInvalid(b, "per-texel file has an id list");
  b = testing::makeBtf(0);
  b.latentRows = 11;
  b.latents.resize(11 * 8);
  expectInvalid(b, "per-texel file has 11 latents for 12 texels");
  b = testing::makeBtf(0);
  b.modulation.terms = 1;
  expectInvalid(b, "per-texel modulation is only defined for the clustered method");
}

TEST(PerTexelNeural, NamesAndNoSweepParameter) {
  const MethodKind& kind = perTexelNeuralMethod();
  EXPECT_EQ(kind.name(), std::string("per-texel-neural"));
  EXPECT_EQ(kind.shortName(), std::string("per-texel"));
  CompressedBtf b = testing::makeBtf(0);
  EXPECT_EQ(kind.summary(b), "per-texel-neural, one latent per texel");
  EXPECT_EQ(kind.sweepParameter(b), 0);
  EXPECT_EQ(kind.need(format::Part::Ids), format::Need::Forbidden);
  EXPECT_EQ(kind.need(format::Part::Latents), format::Need::Required);
  b.planes.resolution = 9, b.planes.features = 2;
  EXPECT_EQ(kind.label(b), "per-texel neural + direction planes (9 x 9 x 2)");
}

}  // namespace
}  // namespace nbtf
