// The decoder's SIMD kernels (codec/decoder_kernels.cpp): every instruction set against a naive reference, and the packed layout.
#include "codec/decoder_kernels.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "codec/decoder.h"
#include "decoder_fixtures.h"

namespace nbtf {
namespace {

using testing::decoderTolerance;
using testing::makeDecoderMaterial;
using testing::probeDirections;
using testing::referenceOutput;
using testing::supportedIsas;

void expectMatchesReference(const NbtfDecoder& dec, const CompressedBtf& b) {
  for (const Direction& l : probeDirections())
    for (const Direction& v : {Direction{0, 0}, Direction{30, 30}, Direction{72, 123}})
      for (int y = 0; y < b.height; ++y)
        for (int x = 0; x < b.width; ++x) {
          std::array<double, 3> mag;
          auto ref = referenceOutput(b, y * b.width + x, l, v, &mag);
          Rgb n = dec.evaluate(x, y, l, v, OutputScale::Normalized);
          const float got[3] = {n.r, n.g, n.b};
          for (int c = 0; c < 3; ++c)
            ASSERT_NEAR(got[c], ref[c], decoderTolerance(mag[c]))
                << decoderIsaName(dec.isa()) << " texel " << x << "," << y << " channel " << c << " light "
                << l.thetaDeg << "," << l.phiDeg;
        }
}

TEST(Decoder, MatchesReferenceOnEveryInstructionSet) {
  // Shapes: the paper's kind (ReLU hidden layers, widths not multiples of 16), a wide
  // layer that needs several column panels, a sigmoid layer, and a single-layer decoder.
  std::vector<std::vector<int>> shapes = {{37, 21}, {130, 5, 17}, {}, {106, 106, 106}};
  for (int k : {5, 0})
    for (const auto& widths : shapes) {
      // Every shape with the paper's direction inputs, the default one with the half vector too.
      for (DirectionEncoding encoding : directionEncodings()) {
      if (encoding != DirectionEncoding::Stereographic && widths != shapes[0]) continue;
      CompressedBtf b = makeDecoderMaterial(k, widths, 7, 5, 11, encoding);
      if (widths.size() == 3 && widths[1] == 5) b.decoder.layers[1].activation = Activation::Sigmoid;
      for (DecoderIsa isa : supportedIsas()) {
        DecoderOptions o;
        o.isa = isa;
        NbtfDecoder dec(b, o);
        EXPECT_EQ(dec.isa(), isa);
        EXPECT_EQ(dec.directionInputs(), directionInputCount(encoding));
        expectMatchesReference(dec, b);
      }
      }
    }
}

// Every layer's outputs padded to whole vectors with zero weights and biases; hidden layers
// transposed (one row per input), the output layer row-major; the first layer split into its
// latent and direction parts.
TEST(DecoderKernels, PackingPadsWithZerosAndSplitsTheFirstLayer) {
  std::mt19937 rng(3);
  const Mlp mlp = testing::makeDecoder(8, {37, 21}, rng);  // 12 -> 37 -> 21 -> 3
  const detail::PackedDecoder p = detail::packDecoder(mlp, 8, 4);
  EXPECT_EQ(detail::padTo(37, 16), 48);
  EXPECT_EQ(detail::padTo(48, 16), 48);
  EXPECT_EQ(p.latentDim, 8);
  EXPECT_EQ(p.dirInputs, 4);
  EXPECT_EQ(p.width0, 37);
  EXPECT_EQ(p.pad0, 48);
  EXPECT_FALSE(p.singleLayer);
  ASSERT_EQ(p.hidden.size(), 1u);
  const DenseLayer& l0 = mlp.layers[0];
  for (int o = 0; o < 48; ++o) {
    EXPECT_EQ(p.bias0.data()[o], o < 37 ? l0.bias[o] : 0.0f) << o;
    for (int q = 0; q < 8; ++q)  // transposed W0_z
      ASSERT_EQ(p.latentWeights.data()[q * 48 + o], o < 37 ? l0.weight[o * 12 + q] : 0.0f) << q << " " << o;
    for (int q = 0; q < 4; ++q)  // transposed W0_dir
      ASSERT_EQ(p.dirWeights.data()[q * 48 + o], o < 37 ? l0.weight[o * 12 + 8 + q] : 0.0f) << q << " " << o;
  }
  const detail::PackedLayer& h = p.hidden[0];
  EXPECT_EQ(h.in, 37);
  EXPECT_EQ(h.out, 21);
  EXPECT_EQ(h.outPad, 32);
  for (int i = 0; i < 37; ++i)
    for (int o = 0; o < 32; ++o)
      ASSERT_EQ(h.weights.data()[i * 32 + o], o < 21 ? mlp.layers[1].weight[o * 37 + i] : 0.0f) << i << " " << o;
  const detail::PackedLayer& out = p.output;
  EXPECT_EQ(out.out, 3);
  EXPECT_EQ(out.inPad, 32);
  for (int o = 0; o < 3; ++o)
    for (int i = 0; i < 32; ++i)
      ASSERT_EQ(out.weights.data()[o * 32 + i], i < 21 ? mlp.layers[2].weight[o * 21 + i] : 0.0f) << o << " " << i;
  EXPECT_EQ(p.maxPad, 48);
}

}  // namespace
}  // namespace nbtf
