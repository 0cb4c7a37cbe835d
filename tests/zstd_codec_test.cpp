#include "codec/zstd_codec.h"

#include <gtest/gtest.h>

#include "test_util.h"

namespace nbtf {
namespace {

std::vector<std::uint8_t> sample() {
  std::vector<std::uint8_t> v(5000);
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = static_cast<std::uint8_t>((i / 37) % 11);
  return v;
}

TEST(ZstdCodec, RoundTripsAndCompressesDeterministically) {
  auto data = sample();
  auto a = zstdCompress(data.data(), data.size()), b = zstdCompress(data.data(), data.size());
  EXPECT_EQ(a, b);
  EXPECT_LT(a.size(), data.size() / 10);
  EXPECT_EQ(zstdDecompress(a.data(), a.size(), data.size(), "f.nbtf", "ids"), data);
}

TEST(ZstdCodec, DamagedOrMismatchedFramesAreClearErrors) {
  auto data = sample();
  auto frame = zstdCompress(data.data(), data.size());
  test::expectErrorContaining([&] { zstdDecompress(frame.data(), frame.size(), data.size() + 1, "f.nbtf", "ids"); },
                                 {"f.nbtf", "ids", "declares 5000 bytes, expected 5001"});
  auto extra = frame;
  extra.push_back(0);
  test::expectErrorContaining([&] { zstdDecompress(extra.data(), extra.size(), data.size(), "f.nbtf", "ids"); },
                                 {"f.nbtf", "unexpected bytes after the zstd frame"});
  std::vector<std::uint8_t> junk = {1, 2, 3, 4, 5, 6, 7, 8, 9};
  test::expectErrorContaining([&] { zstdDecompress(junk.data(), junk.size(), 10, "f.nbtf", "ids"); },
                                 {"f.nbtf", "ids"});
  auto cut = frame;
  cut.resize(cut.size() / 2);
  test::expectErrorContaining([&] { zstdDecompress(cut.data(), cut.size(), data.size(), "f.nbtf", "ids"); },
                                 {"f.nbtf", "ids"});
}

}  // namespace
}  // namespace nbtf
