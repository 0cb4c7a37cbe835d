// The decoding API: agreement with an independent reference evaluation on every
// instruction set, the k-evaluation image path, batches, wrapping, value spaces, and
// every kind of bad input.
#include "codec/decoder.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>

#include <nlohmann/json.hpp>

#include "codec/nbtf_format.h"
#include "codec/pca_model.h"
#include "codec/texel_modulation.h"
#include "codec_fixtures.h"
#include "support/mlp_reference.h"
#include "decoder_fixtures.h"
#include "test_util.h"
#include "util/error.h"
#include "util/parallel.h"

namespace nbtf {
namespace {

using testing::decoderTolerance;
using testing::makeDecoderMaterial;
using testing::probeDirections;
using testing::referenceOutput;
using testing::supportedIsas;

// The plain forward pass (tests/support/mlp_reference.h, Eigen) on the same
// inputs: decoder input = latent | stereographic light | stereographic view.
TEST(Decoder, AgreesWithTheModelsForwardPass) {
  for (int k : {6, 0})
  for (int planeFeatures : {0, 3})
  for (DirectionEncoding encoding : directionEncodings()) {
    CompressedBtf b = makeDecoderMaterial(k, {106, 106, 106}, 9, 4, 11, encoding, planeFeatures);
    NbtfDecoder dec(b);
    std::vector<std::pair<Direction, Direction>> pairs = {{{0, 0}, {0, 0}}, {{37.5, 200}, {10, 45}}, {{75, 345}, {60, 18}}};
    const int dirInputs = b.directionInputs();
    RowMatrix in(b.numTexels() * static_cast<int>(pairs.size()), b.latentDim + dirInputs);
    for (std::size_t p = 0; p < pairs.size(); ++p)
      for (int t = 0; t < b.numTexels(); ++t) {
        auto row = in.row(static_cast<Eigen::Index>(p * b.numTexels() + t));
        for (int q = 0; q < b.latentDim; ++q) row(q) = b.latentOfTexel(t)[q];
        auto d = decoderDirectionInput(b, pairs[p].first, pairs[p].second);
        for (int q = 0; q < dirInputs; ++q) row(b.latentDim + q) = d[q];
      }
    RowMatrix out = mlpForward(b.decoder, in);
    for (std::size_t p = 0; p < pairs.size(); ++p) {
      std::vector<float> img(3 * b.numTexels());
      dec.decodeImage(pairs[p].first, pairs[p].second, img.data(), OutputScale::Normalized);
      for (int t = 0; t < b.numTexels(); ++t) {
        std::array<double, 3> mag;
        referenceOutput(b, t, pairs[p].first, pairs[p].second, &mag);
        for (int c = 0; c < 3; ++c)
          EXPECT_NEAR(img[3 * t + c], out(static_cast<Eigen::Index>(p * b.numTexels() + t), c), 2 * decoderTolerance(mag[c]))
              << "texel " << t << " pair " << p << " channel " << c;
      }
    }
  }
}

TEST(Decoder, AutoPicksTheBestSupportedInstructionSet) {
  NbtfDecoder dec(makeDecoderMaterial(3));
  EXPECT_EQ(dec.isa(), supportedIsas().back());
  EXPECT_EQ(parseDecoderIsa("avx2"), DecoderIsa::Avx2);
  test::expectErrorContaining([] { parseDecoderIsa("sse9"); }, {"unknown instruction set 'sse9'"});
}

TEST(Decoder, LinearIsNormalizedTimesAlpha) {
  CompressedBtf b = makeDecoderMaterial(4);
  NbtfDecoder dec(b);
  for (int x = 0; x < b.width; ++x) {
    Rgb n = dec.evaluate(x, 1, {30, 60}, {45, 20}, OutputScale::Normalized);
    Rgb l = dec.evaluate(x, 1, {30, 60}, {45, 20}, OutputScale::Linear);
    EXPECT_EQ(l.r, n.r * b.alpha);
    EXPECT_EQ(l.g, n.g * b.alpha);
    EXPECT_EQ(l.b, n.b * b.alpha);
  }
}

// The image path evaluates each latent row once and scatters; it must equal evaluating
// every texel on its own (bit for bit) and the naive reference (within float rounding).
TEST(Decoder, ImageFromKEvaluationsEqualsPerTexelEvaluation) {
  for (int k : {4, 0}) {
    CompressedBtf b = makeDecoderMaterial(k, {37, 21}, 9, 6);
    NbtfDecoder dec(b);
    EXPECT_EQ(dec.latentRows(), k > 0 ? k : 54);
    for (const Direction& l : {Direction{15, 60}, Direction{37.5, 200}})
      for (const Direction& v : {Direction{0, 0}, Direction{10, 45}}) {
        std::vector<float> img(3 * 54);
        dec.decodeImage(l, v, img.data(), OutputScale::Linear);
        for (int t = 0; t < 54; ++t) {
          Rgb one = dec.evaluate(t % 9, t / 9, l, v);
          EXPECT_EQ(img[3 * t + 0], one.r);
          EXPECT_EQ(img[3 * t + 1], one.g);
          EXPECT_EQ(img[3 * t + 2], one.b);
          std::array<double, 3> mag;
          auto ref = referenceOutput(b, t, l, v, &mag);
          for (int c = 0; c < 3; ++c) EXPECT_NEAR(img[3 * t + c], ref[c] * b.alpha, decoderTolerance(mag[c] * b.alpha));
        }
      }
  }
}

// Per-texel modulation: every path (image, single, batch by texel and by uv) gives, for
// each texel, the sum of its cluster's R terms weighted by its coefficients (one per term, or
// with `channels` 3 one per term and channel).
void checkModulatedTexelsMix(int channels) {
  SCOPED_TRACE("channels " + std::to_string(channels));
  const int terms = 3, k = 4, columns = terms * channels;
  CompressedBtf b = makeDecoderMaterial(k, {37, 21}, 9, 6);
  CompressedBtf rowsOnly = b;  // the same network with R x 3 outputs, unmodulated, to read the terms
  std::mt19937 rng(4);
  std::normal_distribution<float> normal(0.f, 0.5f);
  DenseLayer& last = b.decoder.layers.back();
  last.out = 3 * terms;
  last.weight.resize(static_cast<std::size_t>(last.in) * last.out);
  last.bias.resize(last.out);
  for (float& w : last.weight) w = normal(rng);
  for (float& x : last.bias) x = normal(rng);
  std::vector<float> raw(54 * columns);
  for (std::size_t i = 0; i < raw.size(); ++i) raw[i] = 0.4f - 0.05f * static_cast<float>((i * 7) % 23);
  b.modulation = quantizeTexelCoefficients(raw, terms, 8, channels);
  NbtfDecoder dec(b);
  ASSERT_TRUE(dec.modulated());
  EXPECT_EQ(dec.modulationTerms(), terms);
  EXPECT_EQ(dec.modulationChannels(), channels);
  const std::vector<float> e = dequantizeTexelCoefficients(b.modulation);
  EXPECT_EQ(dec.texelCoefficients(), e);
  const Direction l{37.5, 200}, v{10, 45};
  std::vector<float> img(3 * 54);
  dec.decodeImage(l, v, img.data(), OutputScale::Normalized);
  {
    // The row terms, then their mix (what the compressor's RMSE reuses): decodeImage's floats,
    // at the material's size and tiled, in both scales.
    std::vector<float> rowTerms(3 * terms * k), mixed(3 * 54);
    dec.decodeRowTerms(l, v, rowTerms.data());
    dec.imageFromRowTerms(rowTerms.data(), mixed.data(), OutputScale::Normalized);
    EXPECT_EQ(mixed, img);
    std::vector<float> tiled(3 * 11 * 8), tiledMixed(3 * 11 * 8);
    dec.decodeImage(l, v, tiled.data(), OutputScale::Linear, 11, 8);
    dec.imageFromRowTerms(rowTerms.data(), tiledMixed.data(), OutputScale::Linear, 11, 8);
    EXPECT_EQ(tiledMixed, tiled);
    test::expectErrorContaining([&] { NbtfDecoder(rowsOnly).imageFromRowTerms(rowTerms.data(), mixed.data()); },
                                {"no per-texel modulation"});
  }
  std::vector<TexelQuery> byTexel;
  std::vector<UvQuery> byUv;
  auto lu = l.unitVector(), vu = v.unitVector();
  for (int t = 0; t < 54; ++t) {
    byTexel.push_back({t % 9, t / 9, l, v});
    byUv.push_back({(t % 9 + 0.5f) / 9, (t / 9 + 0.5f) / 6, {float(lu[0]), float(lu[1]), float(lu[2])},
                    {float(vu[0]), float(vu[1]), float(vu[2])}});
  }
  std::vector<float> batch(3 * 54), uvBatch(3 * 54);
  dec.evaluate(byTexel.data(), byTexel.size(), batch.data(), OutputScale::Normalized);
  dec.evaluate(byUv.data(), byUv.size(), uvBatch.data(), OutputScale::Normalized);
  for (int t = 0; t < 54; ++t) {
    // The naive reference of the network (double), then the texel's mix of its terms.
    std::array<double, 3> mag;
    std::vector<double> term(3 * terms);
    {
      // referenceOutput evaluates 3 outputs; evaluate the R x 3 outputs by hand via Mlp.
      RowMatrix in(1, b.decoder.inputSize());
      const float* z = b.latentOfTexel(t);
      for (int d = 0; d < b.latentDim; ++d) in(0, d) = z[d];
      auto ls = stereographic(l), vs = stereographic(v);
      in(0, b.latentDim) = ls[0], in(0, b.latentDim + 1) = ls[1], in(0, b.latentDim + 2) = vs[0],
                   in(0, b.latentDim + 3) = vs[1];
      RowMatrix out = mlpForward(b.decoder, in);
      for (int o = 0; o < 3 * terms; ++o) term[o] = out(0, o);
    }
    (void)mag;
    for (int c = 0; c < 3; ++c) {
      double want = 0, size = 0;
      for (int r = 0; r < terms; ++r) {
        const double mixed = e[t * columns + r * channels + (channels > 1 ? c : 0)] * term[3 * r + c];
        want += mixed, size += std::fabs(mixed);
      }
      EXPECT_NEAR(img[3 * t + c], want, 1e-4 * (1 + size)) << "texel " << t;
      EXPECT_EQ(batch[3 * t + c], img[3 * t + c]);
      EXPECT_EQ(uvBatch[3 * t + c], img[3 * t + c]);
    }
    Rgb one = dec.evaluate(t % 9, t / 9, l, v, OutputScale::Normalized);
    EXPECT_EQ(one.r, img[3 * t]);
    EXPECT_EQ(one.b, img[3 * t + 2]);
  }
  // Linear is normalized x alpha; rows alone are refused.
  Rgb lin = dec.evaluate(2, 3, l, v), norm = dec.evaluate(2, 3, l, v, OutputScale::Normalized);
  EXPECT_FLOAT_EQ(lin.g, norm.g * b.alpha);
  std::vector<float> rows(3 * k);
  test::expectErrorContaining([&] { dec.decodeRows(l, v, rows.data()); }, {"per-texel modulation", "decodeImage"});
}

TEST(Decoder, ModulatedTexelsMixTheirClusterTermsWithTheirCoefficients) {
  checkModulatedTexelsMix(1);
  checkModulatedTexelsMix(3);
}

// tests/data/legacy_v1_0.nbtf was written by nbtf before format 1.2 (commit 094d9fb, `nbtf
// compress`), and its answers to the queries beside it by that commit's `nbtf query
// --normalized --isa portable`: this build decodes the old file to the same floats.
// A committed file decodes to exactly the values its answers file records (written by the
// `nbtf query --normalized --isa portable` of the commit that made the file).
void expectCommittedAnswers(const std::string& name, int formatMinor, int expectedCount) {
  const std::string dir = std::string(NBTF_SOURCE_DIR) + "/tests/data/";
  DecoderOptions options;
  options.isa = DecoderIsa::Portable;
  NbtfDecoder dec = NbtfDecoder::open(dir + name + ".nbtf", options);
  EXPECT_EQ(dec.material().formatMinor, formatMinor);
  std::ifstream answers(dir + name + ".answers.csv");
  std::string line;
  std::getline(answers, line);  // header
  int count = 0;
  while (std::getline(answers, line)) {
    // Angles as doubles, as `nbtf query` parses them; the answers were printed with 9 digits,
    // which a float survives exactly.
    double v[9];
    ASSERT_EQ(std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf", &v[0], &v[1], &v[2], &v[3], &v[4], &v[5],
                          &v[6], &v[7], &v[8]),
              9)
        << line;
    Rgb c = dec.evaluate(static_cast<int>(v[0]), static_cast<int>(v[1]), {v[2], v[3]}, {v[4], v[5]},
                         OutputScale::Normalized);
    EXPECT_EQ(c.r, static_cast<float>(v[6])) << line;
    EXPECT_EQ(c.g, static_cast<float>(v[7])) << line;
    EXPECT_EQ(c.b, static_cast<float>(v[8])) << line;
    ++count;
  }
  EXPECT_EQ(count, expectedCount);
}

TEST(Decoder, CommittedFormat10FileDecodesAsBefore) { expectCommittedAnswers("legacy_v1_0", 0, 4); }

// Format 1.2 with every compact part (half decoder and latents, zstd ids, per-texel
// modulation), written by commit 12d31f5, before the libraries were split by stage.
TEST(Decoder, CommittedFormat12FileDecodesAsBefore) { expectCommittedAnswers("compact_v1_2", 2, 6); }

// Format 1.4 (8-bit decoder, zstd-coded directions, metadata and hold-out list; half latents,
// zstd ids, modulation), written by commit b352ae2's `nbtf compress` of a 16 x 16 satin
// (`nbtf-synth --preset satin --size 16x16 --layout ubo2003 --seed 3`; `--clusters 8 --epochs 2
// --holdout 0.1 --seed 5 --threads 1`, the default config).
TEST(Decoder, CommittedFormat14FileDecodesAsBefore) {
  expectCommittedAnswers("compact_v1_4", 4, 6);
  const CompressedBtf b = readNbtf(std::string(NBTF_SOURCE_DIR) + "/tests/data/compact_v1_4.nbtf");
  EXPECT_TRUE(b.storage.decoderInt8 && b.storage.directionsZstd && b.storage.metadataZstd);
  EXPECT_EQ(b.holdoutImages.size(), 656u);
  EXPECT_EQ(nlohmann::json::parse(b.metadataJson)["clustering"]["k"].get<int>(), 8);
}

// Format 1.5 (per-channel modulation coefficients, TXCH), written by commit ec2a63a's `nbtf
// compress` of the same satin with the same options and the default config plus
// `"modulation": {"channels": 3}`.
TEST(Decoder, CommittedFormat15FileDecodesAsBefore) {
  expectCommittedAnswers("compact_v1_5", 5, 6);
  const CompressedBtf b = readNbtf(std::string(NBTF_SOURCE_DIR) + "/tests/data/compact_v1_5.nbtf");
  EXPECT_EQ(b.modulation.channels, 3);
  EXPECT_EQ(b.modulation.terms, 1);
}

// A committed default file with Fourier direction inputs: its answers, encoding and first-layer width.
void expectCommittedFourierFile(const std::string& name, int formatMinor, DirectionEncoding encoding, int inputs) {
  expectCommittedAnswers(name, formatMinor, 6);
  const CompressedBtf b = readNbtf(std::string(NBTF_SOURCE_DIR) + "/tests/data/" + name + ".nbtf");
  EXPECT_EQ(b.directionEncoding, encoding);
  EXPECT_EQ(b.decoder.inputSize(), b.latentDim + inputs);
  EXPECT_EQ(b.modulation.channels, 3);
}

// Format 1.6 (Fourier direction inputs at 3 octaves, the default from commit 48bb1be to 9d1460f), written by
// commit 6325403's `nbtf compress` of the same satin with the same options and the default config.
TEST(Decoder, CommittedFormat16FileDecodesAsBefore) {
  expectCommittedFourierFile("compact_v1_6", 6, DirectionEncoding::StereographicFourier, 28);
}

// Format 1.7 (2 octaves, the default since commit 9d1460f), written by commit 9d1460f's `nbtf
// compress` of the same satin with the same options and the default config.
TEST(Decoder, CommittedFormat17FileDecodesAsBefore) {
  expectCommittedFourierFile("compact_v1_7", 7, DirectionEncoding::StereographicFourier2, 20);
}

// Format 1.8 (learned direction planes, DPLN, the default since commit b4d986d), written by
// commit d3471ee's `nbtf compress` of the same satin with the same options and the default config.
TEST(Decoder, CommittedFormat18FileDecodesAsBefore) {
  expectCommittedFourierFile("compact_v1_8", 8, DirectionEncoding::StereographicFourier2, 20 + 12);
  const CompressedBtf b = readNbtf(std::string(NBTF_SOURCE_DIR) + "/tests/data/compact_v1_8.nbtf");
  EXPECT_EQ(b.planes.resolution, 8);
  EXPECT_EQ(b.planes.features, 4);
}

// Format 1.9 (cluster planes, CPLN; configs/high_fidelity.json), written on 2026-11-26 when the
// format was introduced, by `nbtf compress` of the same satin with the same options and
// `--config configs/high_fidelity.json` (cluster planes 6 x 6 x 4, three modulation terms).
TEST(Decoder, CommittedFormat19FileDecodesAsBefore) {
  expectCommittedFourierFile("compact_v1_9", 9, DirectionEncoding::StereographicFourier2, 20 + 12 + 12);
  const CompressedBtf b = readNbtf(std::string(NBTF_SOURCE_DIR) + "/tests/data/compact_v1_9.nbtf");
  EXPECT_EQ(b.clusterPlanes.rows, 8);
  EXPECT_EQ(b.clusterPlanes.resolution, 6);
  EXPECT_EQ(b.clusterPlanes.features, 4);
  EXPECT_EQ(b.modulation.terms, 3);
}

// Format 1.10 (8-bit cluster planes, CPLN value type 2; configs/high_fidelity.json since
// format 1.10), written on 2026-11-27 when the format was introduced, by `nbtf compress` of the
// same satin with the same options and `--config configs/high_fidelity.json` (cluster planes 6 x 6
// x 8 in 8 bits, three modulation terms).
TEST(Decoder, CommittedFormat110FileDecodesAsBefore) {
  expectCommittedFourierFile("compact_v1_10", 10, DirectionEncoding::StereographicFourier2, 20 + 12 + 24);
  const CompressedBtf b = readNbtf(std::string(NBTF_SOURCE_DIR) + "/tests/data/compact_v1_10.nbtf");
  EXPECT_TRUE(b.storage.clusterPlanes8Bit);
  EXPECT_EQ(b.clusterPlanes.rows, 8);
  EXPECT_EQ(b.clusterPlanes.resolution, 6);
  EXPECT_EQ(b.clusterPlanes.features, 8);
  EXPECT_EQ(b.modulation.terms, 3);
}

// Format 1.11 (decorrelated modulation codes, TXCR; the default since format 1.11), written on
// 2026-11-29 when the format was introduced, by `nbtf compress` of the same satin with the same
// options and the default config.
TEST(Decoder, CommittedFormat111FileDecodesAsBefore) {
  expectCommittedFourierFile("compact_v1_11", 11, DirectionEncoding::StereographicFourier2, 20 + 12);
  const CompressedBtf b = readNbtf(std::string(NBTF_SOURCE_DIR) + "/tests/data/compact_v1_11.nbtf");
  EXPECT_TRUE(b.modulation.decorrelated);
  EXPECT_EQ(b.modulation.terms, 1);
  EXPECT_EQ(b.modulation.bits, 7);
}

TEST(Decoder, TextureCoordinatesWrap) {
  CompressedBtf b = makeDecoderMaterial(5, {37, 21}, 7, 5);
  NbtfDecoder dec(b);
  Direction l{30, 60}, v{45, 20};
  for (int y = 0; y < 5; ++y)
    for (int x = 0; x < 7; ++x) {
      float u = (x + 0.5f) / 7, w = (y + 0.5f) / 5;
      Rgb at = dec.evaluate(x, y, l, v);
      for (float du : {0.0f, 1.0f, -1.0f, 3.0f})
        for (float dv : {0.0f, 2.0f, -5.0f}) {
          Rgb uv = dec.evaluateUv(u + du, w + dv, l, v);
          EXPECT_EQ(uv.r, at.r) << x << "," << y << " shifted by " << du << "," << dv;
          EXPECT_EQ(uv.b, at.b);
        }
    }
  EXPECT_EQ(dec.texelOfUv(1.0f, 0.0f), 0);           // u = 1 is the left edge again
  EXPECT_EQ(dec.texelOfUv(-0.01f, 0.0f), 6);         // just left of 0 is the last column
  EXPECT_EQ(dec.texelOfUv(0.0f, -0.01f), 4 * 7);     // just above 0 is the last row
}

TEST(Decoder, LargerImagesTileTheTexture) {
  CompressedBtf b = makeDecoderMaterial(5, {37, 21}, 7, 5);
  NbtfDecoder dec(b);
  std::vector<float> base(3 * 35), big(3 * 16 * 11);
  dec.decodeImage({30, 60}, {45, 20}, base.data());
  dec.decodeImage({30, 60}, {45, 20}, big.data(), OutputScale::Linear, 16, 11);
  for (int y = 0; y < 11; ++y)
    for (int x = 0; x < 16; ++x)
      for (int c = 0; c < 3; ++c)
        EXPECT_EQ(big[3 * (y * 16 + x) + c], base[3 * ((y % 5) * 7 + x % 7) + c]) << x << "," << y;
}

TEST(Decoder, UnitVectorQueriesMatchAngles) {
  for (DirectionEncoding encoding : directionEncodings()) {
  CompressedBtf b = makeDecoderMaterial(5, {37, 21}, 7, 5, 11, encoding);
  NbtfDecoder dec(b);
  std::vector<UvQuery> qs;
  std::vector<Rgb> expect;
  for (const Direction& l : probeDirections())
    for (const Direction& v : {Direction{0, 0}, Direction{72, 123}}) {
      auto lv = l.unitVector(), vv = v.unitVector();
      UvQuery q;
      q.u = 0.3f, q.v = 0.7f;
      // Not unit length on purpose: vectors are normalized.
      q.light = {float(2 * lv[0]), float(2 * lv[1]), float(2 * std::max(lv[2], 0.0))};
      q.view = {float(vv[0]), float(vv[1]), float(std::max(vv[2], 0.0))};
      qs.push_back(q);
      expect.push_back(dec.evaluateUv(q.u, q.v, l, v));
    }
  std::vector<float> rgb(3 * qs.size());
  dec.evaluate(qs.data(), qs.size(), rgb.data());
  for (std::size_t i = 0; i < qs.size(); ++i) {
    EXPECT_NEAR(rgb[3 * i], expect[i].r, 1e-4 * std::max(1.0f, std::fabs(expect[i].r))) << i;
    EXPECT_NEAR(rgb[3 * i + 2], expect[i].b, 1e-4 * std::max(1.0f, std::fabs(expect[i].b))) << i;
    Rgb single = dec.evaluate(qs[i]);
    EXPECT_EQ(single.r, rgb[3 * i]);
  }
  }
}

// A material smooth in direction: values at unmeasured angles are finite and lie between
// those at the neighbouring measured directions.
TEST(Decoder, UnmeasuredAnglesLieBetweenMeasuredNeighbours) {
  CompressedBtf b = testing::makeSmoothMaterial();
  NbtfDecoder dec(b);
  struct Case {
    Direction mid, a, b;
  };
  // Light between two lights of a meridian / of a ring; same for the view.
  const std::vector<Case> lightCases = {{{37.5, 0}, {30, 0}, {45, 0}}, {{30, 15}, {30, 0}, {30, 30}},
                                        {{67.5, 0}, {60, 0}, {75, 0}}, {{7.5, 0}, {0, 0}, {15, 0}}};
  const std::vector<Case> viewCases = {{{45, 50}, {45, 40}, {45, 60}}, {{52.5, 0}, {45, 0}, {60, 0}}};
  auto within = [](float mid, float a, float b) {
    return std::isfinite(mid) && mid >= std::min(a, b) - 1e-6f && mid <= std::max(a, b) + 1e-6f;
  };
  for (int t = 0; t < b.numTexels(); ++t) {
    int x = t % b.width, y = t / b.width;
    for (const Case& c : lightCases) {
      Direction view{30, 30};
      Rgb m = dec.evaluate(x, y, c.mid, view), ra = dec.evaluate(x, y, c.a, view), rb = dec.evaluate(x, y, c.b, view);
      EXPECT_TRUE(within(m.r, ra.r, rb.r) && within(m.g, ra.g, rb.g) && within(m.b, ra.b, rb.b))
          << "light " << c.mid.thetaDeg << "," << c.mid.phiDeg << ": " << m.r << " vs " << ra.r << " .. " << rb.r;
      EXPECT_NE(ra.r, rb.r);  // the neighbours differ, so "between" means something
    }
    for (const Case& c : viewCases) {
      Direction light{15, 0};
      Rgb m = dec.evaluate(x, y, light, c.mid), ra = dec.evaluate(x, y, light, c.a), rb = dec.evaluate(x, y, light, c.b);
      EXPECT_TRUE(within(m.r, ra.r, rb.r) && within(m.g, ra.g, rb.g) && within(m.b, ra.b, rb.b))
          << "view " << c.mid.thetaDeg << "," << c.mid.phiDeg;
    }
    // Both unmeasured at once: inside the range of the four measured corner pairs.
    Direction lm{37.5, 0}, vm{45, 50};
    Rgb m = dec.evaluate(x, y, lm, vm);
    float lo = 1e30f, hi = -1e30f;
    for (const Direction& l : {Direction{30, 0}, Direction{45, 0}})
      for (const Direction& v : {Direction{45, 40}, Direction{45, 60}}) {
        float r = dec.evaluate(x, y, l, v).r;
        lo = std::min(lo, r), hi = std::max(hi, r);
      }
    EXPECT_TRUE(within(m.r, lo, hi)) << m.r << " not in " << lo << " .. " << hi;
  }
}

// ---- Bad input -------------------------------------------------------------------------

TEST(Decoder, TexelOutsideTheMaterialIsAnError) {
  NbtfDecoder dec(makeDecoderMaterial(5, {37, 21}, 7, 5));
  for (auto [x, y] : {std::pair{7, 0}, std::pair{0, 5}, std::pair{-1, 2}})
    test::expectErrorContaining([&, x = x, y = y] { dec.evaluate(x, y, {0, 0}, {0, 0}); },
                                   {"texel (" + std::to_string(x) + ", " + std::to_string(y) + ")",
                                    "outside the 7 x 5 material"});
}

TEST(Decoder, DirectionsBelowTheHorizonAreErrors) {
  NbtfDecoder dec(makeDecoderMaterial(5));
  test::expectErrorContaining([&] { dec.evaluate(0, 0, {95, 0}, {0, 0}); },
                                 {"light direction theta = 95", "outside the upper hemisphere"});
  test::expectErrorContaining([&] { dec.evaluate(0, 0, {0, 0}, {-3, 0}); }, {"view direction theta = -3"});
  test::expectErrorContaining([&] { dec.evaluate(0, 0, {NAN, 0}, {0, 0}); }, {"light direction is not finite"});
  std::vector<float> img(3 * 35);
  test::expectErrorContaining([&] { dec.decodeImage({30, 0}, {91, 0}, img.data()); }, {"view direction theta = 91"});
  UvQuery q;
  q.view = {0.3f, 0.2f, -0.1f};
  test::expectErrorContaining([&] { dec.evaluate(q); }, {"view direction", "below the horizon"});
  q.view = {0, 0, 0};
  test::expectErrorContaining([&] { dec.evaluate(q); }, {"view direction vector has zero length"});
  q.view = {0, 0, 1};
  q.u = INFINITY;
  test::expectErrorContaining([&] { dec.evaluate(q); }, {"texture coordinate (u, v) is not finite"});
}

TEST(Decoder, BatchErrorsNameTheQueryAndComputeNothing) {
  NbtfDecoder dec(makeDecoderMaterial(5, {37, 21}, 7, 5));
  std::vector<TexelQuery> qs(10, TexelQuery{1, 1, {10, 10}, {20, 20}});
  qs[6].x = 9;
  std::vector<float> rgb(30, -7.0f);
  test::expectErrorContaining([&] { dec.evaluate(qs.data(), qs.size(), rgb.data()); },
                                 {"query 6: texel (9, 1) is outside"});
  EXPECT_EQ(rgb[0], -7.0f);
}

TEST(Decoder, OpenReportsMissingAndDamagedFiles) {
  test::TempDir dir;
  test::expectErrorContaining([&] { NbtfDecoder::open(dir / "missing.nbtf"); }, {"missing.nbtf", "cannot open"});
  std::string path = dir / "m.nbtf";
  writeNbtf(path, makeDecoderMaterial(5));
  NbtfDecoder dec = NbtfDecoder::open(path);
  EXPECT_EQ(dec.name(), path);
  EXPECT_EQ(dec.width(), 7);
  // Truncate: the reader's error names the file.
  std::filesystem::resize_file(path, 100);
  test::expectErrorContaining([&] { NbtfDecoder::open(path); }, {path, "truncated"});
}

TEST(Decoder, FlopsCountEveryLayer) {
  NbtfDecoder dec(makeDecoderMaterial(5, {106, 106, 106}));
  // The paper's decoder shape: 12 -> 106 -> 106 -> 106 -> 3.
  EXPECT_EQ(dec.flopsPerEvaluation(), 2.0 * (12 * 106 + 106 * 106 * 2 + 106 * 3));
}

// ---- PCA baseline files, through the same API

// A PCA material on the 81-direction hemisphere (9 lights x 9 views), C = 5.
CompressedBtf pcaMaterial() {
  CompressedBtf b = testing::makePcaBtf(5, 4, 3);
  const auto& h = hemisphere81();
  b.lights.clear();
  b.views.clear();
  for (int i : {0, 1, 2, 7, 8, 19, 20, 37, 38}) b.lights.push_back(h[i]), b.views.push_back(h[i]);
  std::mt19937 rng(5);
  std::normal_distribution<float> normal(0.f, 1.f);
  b.pcaMean.resize(3 * static_cast<std::size_t>(b.numImages()));
  for (float& m : b.pcaMean) m = 0.5f + 0.1f * normal(rng);
  b.pcaBasis.resize(b.pcaMean.size() * 5);
  for (float& x : b.pcaBasis) x = 0.2f * normal(rng);
  b.holdoutImages = {3, 40};
  return b;
}

TEST(Decoder, PcaReproducesMeanPlusCoefficientsTimesBasisAtMeasuredPairs) {
  const CompressedBtf b = pcaMaterial();
  NbtfDecoder dec(b);
  EXPECT_TRUE(dec.pca());
  EXPECT_FALSE(dec.clustered());
  EXPECT_EQ(dec.latentRows(), 12);
  EXPECT_DOUBLE_EQ(dec.flopsPerEvaluation(), 6.0 * 5);
  const int nv = static_cast<int>(b.views.size());
  std::vector<float> image(3 * 12), normalized(3 * 12);
  for (int img = 0; img < b.numImages(); ++img) {
    const Direction& l = b.lights[img / nv];
    const Direction& v = b.views[img % nv];
    dec.decodeImage(l, v, image.data());
    dec.decodeImage(l, v, normalized.data(), OutputScale::Normalized);
    for (int t = 0; t < 12; ++t)
      for (int c = 0; c < 3; ++c) {
        const double expected = testing::pcaValue(b, t, img, c);
        ASSERT_NEAR(normalized[3 * t + c], expected, 1e-5) << "image " << img << " texel " << t;
        ASSERT_EQ(image[3 * t + c], normalized[3 * t + c] * b.alpha);
      }
    // Single queries, batches and texture coordinates give the same bits as the image.
    Rgb one = dec.evaluate(3, 2, l, v, OutputScale::Normalized);
    EXPECT_EQ(one.r, normalized[3 * 11 + 0]);
    EXPECT_EQ(one.b, normalized[3 * 11 + 2]);
    Rgb uv = dec.evaluateUv(0.3f, 0.1f, l, v, OutputScale::Normalized);  // texel (1, 0)
    EXPECT_EQ(uv.g, normalized[3 * 1 + 1]);
  }
  std::vector<TexelQuery> queries;
  for (int i = 0; i < 5000; ++i) queries.push_back({i % 4, (i / 4) % 3, b.lights[i % 9], b.views[(i / 7) % 9]});
  std::vector<float> batch(3 * queries.size());
  dec.evaluate(queries.data(), queries.size(), batch.data());
  for (std::size_t i = 0; i < queries.size(); i += 97) {
    Rgb one = dec.evaluate(queries[i].x, queries[i].y, queries[i].light, queries[i].view);
    ASSERT_EQ(batch[3 * i], one.r) << i;
    ASSERT_EQ(batch[3 * i + 2], one.b) << i;
  }
}

TEST(Decoder, PcaUnmeasuredPairIsTheWeightedBlendOfItsNeighbours) {
  const CompressedBtf b = pcaMaterial();
  NbtfDecoder dec(b);
  const int nv = static_cast<int>(b.views.size());
  DirectionInterpolator interp(b.lights, b.views);
  const Direction light{15, 30}, view{37.5, 25};  // neither measured
  auto weights = interp.weights(light, view);
  ASSERT_GE(weights.size(), 2u);
  std::vector<float> image(3 * 12);
  dec.decodeImage(light, view, image.data(), OutputScale::Normalized);
  for (int t = 0; t < 12; ++t)
    for (int c = 0; c < 3; ++c) {
      // PCA is linear: blending mean and basis rows blends the neighbours' values.
      double blend = 0, lo = 1e30, hi = -1e30;
      for (const ImageWeight& w : weights) {
        double value = testing::pcaValue(b, t, w.image, c);
        blend += w.weight * value;
        lo = std::min(lo, value), hi = std::max(hi, value);
      }
      EXPECT_NEAR(image[3 * t + c], blend, 1e-5) << t << " " << c;
      EXPECT_GE(image[3 * t + c], lo - 1e-5);
      EXPECT_LE(image[3 * t + c], hi + 1e-5);
    }
  // The blend uses measured neighbours of both directions, nearest first.
  EXPECT_EQ(weights[0].image / nv, 1);  // light (15, 0) or (15, 60): equidistant, lowest index first
  EXPECT_TRUE(weights[1].image / nv == 2 || weights[1].image / nv == 1);
  // Bad input is checked as for the neural methods.
  EXPECT_THROW(dec.evaluate(4, 0, light, view), Error);
  EXPECT_THROW(dec.evaluate(0, 0, Direction{95, 0}, view), Error);
}

}  // namespace
}  // namespace nbtf

namespace nbtf {
namespace {

// Images, texel queries, UV queries and single evaluations of `b` agree with the naive
// reference (which samples the texel's own latent row) at three light / view pairs.
void expectEveryQueryFormMatchesReference(const CompressedBtf& b) {
  using testing::decoderTolerance;
  using testing::referenceOutput;
  NbtfDecoder dec(b);
  const std::vector<std::pair<Direction, Direction>> pairs = {{{0, 0}, {0, 0}}, {{37.5, 200}, {10, 45}},
                                                              {{75, 345}, {60, 18}}};
  for (const auto& [l, v] : pairs) {
    std::vector<float> img(3 * b.numTexels()), byTexel(3 * b.numTexels()), byUv(3 * b.numTexels());
    dec.decodeImage(l, v, img.data(), OutputScale::Normalized);
    std::vector<TexelQuery> tq;
    std::vector<UvQuery> uq;
    const auto lu = l.unitVector(), vu = v.unitVector();
    for (int t = 0; t < b.numTexels(); ++t) {
      tq.push_back({t % b.width, t / b.width, l, v});
      uq.push_back({(t % b.width + 0.5f) / b.width, (t / b.width + 0.5f) / b.height,
                    {float(lu[0]), float(lu[1]), float(lu[2])}, {float(vu[0]), float(vu[1]), float(vu[2])}});
    }
    dec.evaluate(tq.data(), tq.size(), byTexel.data(), OutputScale::Normalized);
    dec.evaluate(uq.data(), uq.size(), byUv.data(), OutputScale::Normalized);
    for (int t = 0; t < b.numTexels(); ++t) {
      std::array<double, 3> mag;
      const std::array<double, 3> want = referenceOutput(b, t, l, v, &mag);
      const Rgb one = dec.evaluate(t % b.width, t / b.width, l, v, OutputScale::Normalized);
      EXPECT_EQ(one.r, byTexel[3 * t]) << "texel " << t;
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(img[3 * t + c], want[c], 2 * decoderTolerance(mag[c])) << "texel " << t;
        EXPECT_EQ(byTexel[3 * t + c], img[3 * t + c]) << "texel " << t;
        // UV queries arrive as float unit vectors: the same pair to float precision.
        EXPECT_NEAR(byUv[3 * t + c], want[c], 1e-4 + 1e-4 * mag[c]) << "texel " << t;
      }
    }
  }
}

// `b` stored (float32 or half; cluster planes in 8 bits when `eightBit`), written and read back:
// the file is format 1.`minor`, writes the same bytes again and decodes bit for bit as the
// stored material. Returns what was read.
CompressedBtf expectRoundTripDecodesTheSame(const CompressedBtf& b, bool half, int minor, bool eightBit = false) {
  CompressedBtf stored = b;
  stored.storage.decoderHalf = half;
  stored.storage.clusterPlanes8Bit = eightBit;
  roundToStorage(stored);
  const std::vector<std::uint8_t> bytes = serializeNbtf(stored);
  EXPECT_EQ(bytes[10], minor);
  CompressedBtf back = parseNbtf(bytes.data(), bytes.size(), "mem");
  EXPECT_EQ(back.planes.values, stored.planes.values);
  EXPECT_EQ(back.clusterPlanes.values, stored.clusterPlanes.values);
  EXPECT_EQ(serializeNbtf(back), bytes);
  std::vector<float> a(3 * b.numTexels()), c(3 * b.numTexels());
  NbtfDecoder(stored).decodeImage({37.5, 200}, {10, 45}, a.data(), OutputScale::Normalized);
  NbtfDecoder(back).decodeImage({37.5, 200}, {10, 45}, c.data(), OutputScale::Normalized);
  EXPECT_EQ(a, c);
  return back;
}

// A material with learned direction planes (format 1.8) serves every query form and survives a
// round trip through the file (float32 and half storage).
TEST(Decoder, DirectionPlanesServeEveryQueryFormAndRoundTrip) {
  CompressedBtf b =
      testing::makeDecoderMaterial(5, {37, 21}, 7, 5, 11, DirectionEncoding::StereographicFourier2, 3);
  EXPECT_EQ(NbtfDecoder(b).directionInputs(), 20 + 9);
  expectEveryQueryFormMatchesReference(b);
  for (bool half : {false, true}) {
    const CompressedBtf back = expectRoundTripDecodesTheSame(b, half, 8);
    EXPECT_EQ(computeSizes(back).planes, 3u * 6 * 6 * 3 * (half ? 2 : 4));
  }
}

// Cluster planes (format 1.9, CPLN): each latent row's own planes, for a clustered and a
// per-texel material.
TEST(Decoder, ClusterPlanesServeEveryQueryFormAndRoundTrip) {
  for (int k : {5, 0}) {
    SCOPED_TRACE("k " + std::to_string(k));
    CompressedBtf b =
        testing::makeDecoderMaterial(k, {37, 21}, 7, 5, 11, DirectionEncoding::StereographicFourier2, 3, 2);
    EXPECT_EQ(NbtfDecoder(b).directionInputs(), 20 + 9 + 6);
    expectEveryQueryFormMatchesReference(b);
    for (bool half : {false, true}) {
      const CompressedBtf back = expectRoundTripDecodesTheSame(b, half, 9);
      EXPECT_EQ(back.clusterPlanes.rows, b.latentRows);
      EXPECT_EQ(computeSizes(back).clusterPlanes,
                static_cast<std::uint64_t>(b.latentRows) * 3 * 4 * 4 * 2 * (half ? 2 : 4));
    }
    // 8-bit (format 1.10): a code per value and a float32 range per row and feature.
    const CompressedBtf back = expectRoundTripDecodesTheSame(b, true, 10, true);
    EXPECT_TRUE(back.storage.clusterPlanes8Bit);
    EXPECT_EQ(computeSizes(back).clusterPlanes, static_cast<std::uint64_t>(b.latentRows) * (3 * 4 * 4 * 2 + 2 * 8));
    EXPECT_NE(storageDescription(back).find("cluster planes 8-bit"), std::string::npos) << storageDescription(back);
  }
}

// 8-bit cluster planes: every value within half a code step of what was trained, each row's
// and feature's extremes kept exactly, and the decoded values code to themselves again.
TEST(Decoder, ClusterPlanes8BitCodesAreWithinHalfAStepAndStable) {
  CompressedBtf b =
      testing::makeDecoderMaterial(6, {37, 21}, 7, 5, 11, DirectionEncoding::StereographicFourier2, 0, 3);
  RowPlanes& p = b.clusterPlanes;
  p.values[5] = 1000.f;  // one wide range, and a feature whose values are all equal
  for (std::size_t i = 2; i < p.valuesPerRow(); i += p.features) p.values[p.valuesPerRow() + i] = 0.25f;
  const RowPlanes trained = p;
  const std::vector<float> ranges = format::clusterPlaneRanges(trained);
  format::roundClusterPlanesTo8Bit(p);
  EXPECT_EQ(format::clusterPlaneRanges(p), ranges);
  EXPECT_TRUE(format::clusterPlanes8BitExact(p));
  EXPECT_FALSE(format::clusterPlanes8BitExact(trained));
  int distinct = 0;
  for (std::size_t i = 0; i < p.values.size(); ++i) {
    const float* r = &ranges[(i / p.valuesPerRow() * p.features + i % p.features) * 2];
    EXPECT_LE(std::fabs(p.values[i] - trained.values[i]), (r[1] - r[0]) / 510 * (1 + 1e-5f) + 1e-7f) << i;
    EXPECT_GE(p.values[i], r[0]);
    EXPECT_LE(p.values[i], r[1]);
    distinct += p.values[i] != trained.values[i];
  }
  EXPECT_GT(distinct, 0);
  EXPECT_EQ(p.values[p.valuesPerRow() + 2], 0.25f);
  EXPECT_EQ(format::planeCode(0.25f, 0.25f, 0.25f), 0);
  EXPECT_EQ(format::planeCodeValue(0, -1, 3), -1.f);
  EXPECT_EQ(format::planeCodeValue(255, -1, 3), 3.f);
  EXPECT_EQ(format::planeCode(1.f, -1, 3), 128);  // 127.5 rounds to even

  // Values the codes cannot represent are refused by name, not stored as something else.
  CompressedBtf unrounded = b;
  unrounded.clusterPlanes = trained;
  unrounded.storage.clusterPlanes8Bit = true;
  test::expectErrorContaining([&] { unrounded.validate("m.nbtf"); },
                              {"m.nbtf", "cluster planes are to be stored in 8 bits"});
}

TEST(Decoder, ClusterPlanesContentIsCheckedByName) {
  const CompressedBtf b =
      testing::makeDecoderMaterial(5, {37, 21}, 7, 5, 11, DirectionEncoding::StereographicFourier2, 0, 2);
  CompressedBtf bad = b;
  bad.clusterPlanes.values.pop_back();
  test::expectErrorContaining([&] { bad.validate("m.nbtf"); }, {"m.nbtf", "cluster planes hold 479 values, expected 480"});
  bad = b;
  bad.clusterPlanes.values[7] = std::nanf("");
  test::expectErrorContaining([&] { bad.validate("m.nbtf"); }, {"cluster planes contain non-finite values"});
  bad = b;
  bad.clusterPlanes.rows = 4;
  test::expectErrorContaining([&] { bad.validate("m.nbtf"); }, {"cluster planes have 4 rows, expected one per latent row (5)"});
  bad = b;
  bad.clusterPlanes = RowPlanes{};  // the decoder still takes their inputs
  test::expectErrorContaining([&] { bad.validate("m.nbtf"); }, {"decoder layer 0 takes 34 inputs, expected 28"});
}

TEST(Decoder, DirectionPlanesContentIsCheckedByName) {
  CompressedBtf b = testing::makeDecoderMaterial(5, {37, 21}, 7, 5, 11, DirectionEncoding::StereographicFourier2, 2);
  CompressedBtf bad = b;
  bad.planes.values.pop_back();
  test::expectErrorContaining([&] { bad.validate("m.nbtf"); }, {"m.nbtf", "direction planes hold 215 values, expected 216"});
  bad = b;
  bad.planes.values[5] = std::nanf("");
  test::expectErrorContaining([&] { bad.validate("m.nbtf"); }, {"direction planes contain non-finite values"});
  bad = b;
  bad.planes = DirectionPlanes{};  // the decoder still takes the planes' inputs
  test::expectErrorContaining([&] { bad.validate("m.nbtf"); }, {"decoder layer 0 takes 34 inputs, expected 28"});
}

}  // namespace
}  // namespace nbtf
