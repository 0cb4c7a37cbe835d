// What the two neural kinds share (codec/methods/neural.cpp): the decoder, planes and latents checks, the planes label, the info lines.
#include "codec/methods/neural.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <string>

#include "codec_fixtures.h"
#include "test_util.h"

namespace nbtf {
namespace {

void expectInvalid(const CompressedBtf& b, const std::string& part) {
  test::expectErrorContaining([&] { validateNeuralParts(b, "n.nbtf"); }, {"n.nbtf", part});
}

TEST(NeuralKind, DecoderAndLatentsAreChecked) {
  EXPECT_NO_THROW(validateNeuralParts(testing::makeBtf(5), "n.nbtf"));
  CompressedBtf b = testing::makeBtf(5);
  b.decoder.layers.clear();
  expectInvalid(b, "decoder has no layers");
  b = testing::makeBtf(5);
  b.decoder.layers[1].in += 1;
  expectInvalid(b, "decoder layer 1 takes 7 inputs, expected 6 (previous layer's outputs)");
  b = testing::makeBtf(5);
  b.decoder.layers[0].bias[0] = NAN;
  expectInvalid(b, "decoder layer 0 has non-finite parameters");
  b = testing::makeBtf(5);
  b.latents.pop_back();
  expectInvalid(b, "latents hold 39 values, expected 5 x 8");
  b = testing::makeBtf(5);
  b.latents[2] = INFINITY;
  expectInvalid(b, "latents contain non-finite values");
  b = testing::makeBtf(5);
  b.pcaMean = {1.0f};
  expectInvalid(b, "clustered-neural file has a PCA mean or basis");
  b = testing::makeBtf(5);
  b.storage.latentsHalf = true;
  b.latents[0] = 0.1f;  // not a half value
  expectInvalid(b, "latents are to be stored in half precision");
}

TEST(NeuralKind, PlanesAreCheckedAndLabelled) {
  CompressedBtf b = testing::makeBtf(5);
  EXPECT_EQ(planesLabel(b), "");
  b.planes.values = {1.0f};  // values without features
  expectInvalid(b, "direction plane values without features");
  b = testing::makeBtf(5);
  b.clusterPlanes.features = 2;
  b.clusterPlanes.resolution = 4;
  b.clusterPlanes.rows = 4;
  std::mt19937 rng(1);
  b.decoder = testing::makeDecoder(8, {6, 5}, rng, 4 + b.clusterPlanes.inputCount());  // their decoder inputs
  expectInvalid(b, "cluster planes have 4 rows, expected one per latent row (5)");
  b.planes.features = 2;
  b.planes.resolution = 9;
  EXPECT_EQ(planesLabel(b), " + direction planes (9 x 9 x 2) + cluster planes (4 x 4 x 2)");
}

TEST(NeuralKind, InfoFieldsDescribeTheNeuralParts) {
  const CompressedBtf b = testing::makeBtf(5);
  std::map<std::string, std::string> fields;
  for (const auto& [name, value] : methodKind(b.method).infoFields(b)) fields[name] = value;
  EXPECT_EQ(fields["latents"], "5 x 8");
  EXPECT_EQ(fields["alpha"], "1.75 (decoder output x alpha = linear RGB)");
  EXPECT_EQ(fields["decoder"].rfind("12 -> 6 (", 0), 0u) << fields["decoder"];
  EXPECT_NE(fields["decoder"].find("-> 3 ("), std::string::npos) << fields["decoder"];
  EXPECT_EQ(fields.count("planes"), 0u);
  EXPECT_EQ(fields.count("modulation"), 0u);
  EXPECT_EQ(fields.count("directions"), 1u);
  EXPECT_EQ(fields.count("storage"), 1u);
}

}  // namespace
}  // namespace nbtf
