// The model kinds behind codec/methods/method.h: the registry, each kind's parts, names and
// checks, and the decoder holding the kind's evaluator.
#include <gtest/gtest.h>

#include "codec/decoder.h"
#include "codec/methods/method.h"
#include "codec_fixtures.h"
#include "test_util.h"

namespace nbtf {
namespace {

using format::Need;
using format::Part;

TEST(MethodRegistry, EveryStoredCodeHasItsKindAndAnUnknownOneIsRefusedByName) {
  ASSERT_EQ(methodKinds().size(), 3u);
  EXPECT_EQ(methodKind(CodecMethod::ClusteredNeural).name(), std::string("clustered-neural"));
  EXPECT_EQ(methodKind(CodecMethod::PerTexelNeural).name(), std::string("per-texel-neural"));
  EXPECT_EQ(methodKind(CodecMethod::Pca).name(), std::string("pca"));
  for (const MethodKind* kind : methodKinds()) {
    EXPECT_EQ(findMethodKind(kind->code()), kind);
    EXPECT_EQ(codecMethodName(kind->code()), kind->name());
  }
  EXPECT_EQ(findMethodKind(static_cast<CodecMethod>(9)), nullptr);
  EXPECT_EQ(codecMethodName(static_cast<CodecMethod>(9)), "unknown");
  test::expectErrorContaining([] { methodKind(static_cast<CodecMethod>(9), "odd.nbtf"); },
                              {"odd.nbtf", "unknown method code 9"});
}

// The parts each kind stores, as the format defines them (docs/file_format.md): R required,
// F forbidden, O optional; columns clustered, per-texel, PCA.
TEST(MethodRegistry, EachKindNeedsThePartsTheFormatDefinesForIt) {
  const Need R = Need::Required, F = Need::Forbidden, O = Need::Optional;
  struct Row {
    Part part;
    Need clustered, perTexel, pca;
  };
  const Row rows[] = {
      {Part::Info, R, R, R},       {Part::Directions, R, R, R},      {Part::Decoder, R, R, F},
      {Part::Latents, R, R, F},    {Part::PcaMean, F, F, R},         {Part::PcaBasis, F, F, R},
      {Part::PcaCoefficients, F, F, R}, {Part::Ids, R, F, F},        {Part::Modulation, O, F, F},
      {Part::Planes, O, O, O},     {Part::ClusterPlanes, O, O, F},   {Part::Holdout, O, O, O},
      {Part::Encoder, O, O, O},    {Part::Metadata, O, O, O},
  };
  ASSERT_EQ(std::size(rows), format::checkedParts().size());
  for (const Row& r : rows) {
    SCOPED_TRACE(static_cast<int>(r.part));
    EXPECT_EQ(clusteredNeuralMethod().need(r.part), r.clustered);
    EXPECT_EQ(perTexelNeuralMethod().need(r.part), r.perTexel);
    EXPECT_EQ(pcaMethod().need(r.part), r.pca);
  }
  EXPECT_EQ(soleKindRequiring(Part::Ids), &clusteredNeuralMethod());
  EXPECT_EQ(soleKindRequiring(Part::PcaBasis), &pcaMethod());
  EXPECT_EQ(soleKindRequiring(Part::Decoder), nullptr);  // both neural kinds
  EXPECT_EQ(soleKindRequiring(Part::Modulation), nullptr);
}

TEST(MethodRegistry, EachKindDescribesItsMaterial) {
  const CompressedBtf clustered = testing::makeBtf(5), perTexel = testing::makeBtf(0), pca = testing::makePcaBtf(3);
  EXPECT_EQ(methodKind(clustered.method).summary(clustered), "clustered-neural, k = 5 clusters");
  EXPECT_EQ(methodKind(clustered.method).label(clustered), "clustered neural, k = 5");
  EXPECT_EQ(methodKind(clustered.method).sweepParameter(clustered), 5);
  EXPECT_EQ(methodKind(perTexel.method).summary(perTexel), "per-texel-neural, one latent per texel");
  EXPECT_EQ(methodKind(perTexel.method).label(perTexel), "per-texel neural");
  EXPECT_EQ(methodKind(perTexel.method).sweepParameter(perTexel), 0);
  EXPECT_EQ(methodKind(pca.method).summary(pca), "pca (classic baseline), C = 3 components");
  EXPECT_EQ(methodKind(pca.method).label(pca), "PCA, C = 3");
  EXPECT_EQ(methodKind(pca.method).sweepParameter(pca), 3);
}

// Each kind's own invariants run through CompressedBtf::validate.
TEST(MethodRegistry, EachKindChecksItsOwnParts) {
  CompressedBtf clustered = testing::makeBtf(5);
  clustered.ids[3] = 5;
  test::expectErrorContaining([&] { clustered.validate("c.nbtf"); }, {"c.nbtf", "id of texel 3 is 5, outside [0, 5)"});
  CompressedBtf perTexel = testing::makeBtf(0);
  perTexel.ids.assign(static_cast<std::size_t>(perTexel.numTexels()), 0);
  test::expectErrorContaining([&] { perTexel.validate("p.nbtf"); }, {"p.nbtf", "per-texel file has an id list"});
  CompressedBtf pca = testing::makePcaBtf(3);
  pca.pcaMean.pop_back();
  test::expectErrorContaining([&] { pca.validate("b.nbtf"); }, {"b.nbtf", "PCA mean holds"});
  CompressedBtf unknown = testing::makeBtf(5);
  unknown.method = static_cast<CodecMethod>(7);
  test::expectErrorContaining([&] { unknown.validate("u.nbtf"); }, {"u.nbtf", "unknown method code 7"});
}

// The decoder evaluates through its kind's evaluator: a clustered material's texels are copies
// of their rows, a per-texel material's rows are its texels, PCA's FLOPs are its dot products.
TEST(MethodRegistry, TheDecoderHoldsItsKindsEvaluator) {
  const NbtfDecoder clustered(testing::makeBtf(5));
  std::vector<float> rows(3 * 5), image(3 * static_cast<std::size_t>(clustered.numTexels()));
  clustered.decodeRows({15, 0}, {30, 30}, rows.data());
  clustered.decodeImage({15, 0}, {30, 30}, image.data());
  for (int t = 0; t < clustered.numTexels(); ++t)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(image[3 * t + c], rows[3 * clustered.latentRowOfTexel(t) + c]);
  double flops = 0;
  for (const DenseLayer& l : clustered.material().decoder.layers) flops += 2.0 * l.in * l.out;
  EXPECT_EQ(clustered.flopsPerEvaluation(), flops);
  const NbtfDecoder pca(testing::makePcaBtf(3));
  EXPECT_EQ(pca.flopsPerEvaluation(), 18.0);
  std::vector<float> terms(3 * 12);
  test::expectErrorContaining([&] { pca.decodeRowTerms({0, 0}, {0, 0}, terms.data()); }, {"no decoder terms"});
}

}  // namespace
}  // namespace nbtf
