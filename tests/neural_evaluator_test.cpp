// The decoder MLP's evaluator (codec/methods/neural_evaluator.cpp): rows decoded once per cluster, batches in tiles equal to single queries, the first-layer cache.
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "codec/decoder.h"
#include "decoder_fixtures.h"
#include "util/parallel.h"

namespace nbtf {
namespace {

using testing::makeDecoderMaterial;

TEST(Decoder, DecodeRowsGivesOneValuePerCluster) {
  CompressedBtf b = makeDecoderMaterial(6, {37, 21}, 8, 8);
  NbtfDecoder dec(b);
  std::vector<float> rows(3 * 6), img(3 * 64);
  dec.decodeRows({45, 100}, {30, 30}, rows.data(), OutputScale::Normalized);
  dec.decodeImage({45, 100}, {30, 30}, img.data(), OutputScale::Normalized);
  for (int t = 0; t < 64; ++t)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(img[3 * t + c], rows[3 * b.ids[t] + c]);
}

TEST(Decoder, BatchEqualsSingleQueries) {
  // Large enough to run on several threads and many tiles; directions repeat in runs
  // (the batch shares their first-layer work) and also change on every query.
  setThreadCount(2);
  for (int k : {5, 0})
  for (DirectionEncoding encoding : directionEncodings()) {
    CompressedBtf b = makeDecoderMaterial(k, {37, 21}, 7, 5, 11, encoding);
    NbtfDecoder dec(b);
    std::mt19937 rng(3);
    std::uniform_int_distribution<int> xs(0, b.width - 1), ys(0, b.height - 1);
    std::uniform_real_distribution<double> theta(0, 90), phi(0, 360);
    std::vector<TexelQuery> queries(6000);
    for (std::size_t i = 0; i < queries.size(); ++i) {
      TexelQuery& q = queries[i];
      q.x = xs(rng), q.y = ys(rng);
      if (i % 100 < 50 && i > 0) {
        q.light = queries[i - 1].light, q.view = queries[i - 1].view;
      } else {
        q.light = {theta(rng), phi(rng)}, q.view = {theta(rng), phi(rng)};
      }
    }
    std::vector<float> rgb(3 * queries.size());
    dec.evaluate(queries.data(), queries.size(), rgb.data());
    for (std::size_t i = 0; i < queries.size(); i += 7) {
      Rgb one = dec.evaluate(queries[i].x, queries[i].y, queries[i].light, queries[i].view);
      ASSERT_EQ(rgb[3 * i + 0], one.r) << "query " << i;
      ASSERT_EQ(rgb[3 * i + 1], one.g) << "query " << i;
      ASSERT_EQ(rgb[3 * i + 2], one.b) << "query " << i;
    }
  }
  setThreadCount(0);
}

TEST(Decoder, UncachedFirstLayerGivesIdenticalResults) {
  CompressedBtf b = makeDecoderMaterial(0, {37, 21});
  DecoderOptions uncached;
  uncached.maxCachedFirstLayerBytes = 0;
  NbtfDecoder a(b), c(b, uncached);
  std::vector<float> ia(3 * b.numTexels()), ic(3 * b.numTexels());
  a.decodeImage({20, 40}, {50, 80}, ia.data());
  c.decodeImage({20, 40}, {50, 80}, ic.data());
  EXPECT_EQ(ia, ic);
}

}  // namespace
}  // namespace nbtf
