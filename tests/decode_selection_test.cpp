// pipeline/decode_selection.h: --lights / --views lists and --size.
#include "pipeline/decode_selection.h"

#include <gtest/gtest.h>

#include "test_util.h"

namespace nbtf {
namespace {

TEST(DecodeSelection, DirectionListsAndSizes) {
  const auto& dirs = hemisphere81();
  auto idx = [](const std::vector<DirectionChoice>& c) {
    std::vector<int> out;
    for (const auto& d : c) out.push_back(d.index);
    return out;
  };
  EXPECT_EQ(parseDirectionList("all", dirs, "--lights").size(), 81u);
  EXPECT_EQ(idx(parseDirectionList("3-5,1,4", dirs, "--lights")), (std::vector<int>{3, 4, 5, 1}));
  EXPECT_EQ(idx(parseDirectionList("t15p60", dirs, "--lights")), std::vector<int>{2});  // ring 15: 0, 60, ...
  EXPECT_EQ(idx(parseDirectionList("t15p420", dirs, "--lights")), std::vector<int>{2});  // phi wraps
  EXPECT_EQ(idx(parseDirectionList("t0p90", dirs, "--lights")), std::vector<int>{0});    // the pole
  auto un = parseDirectionList("t37.5p-160", dirs, "--views");
  ASSERT_EQ(un.size(), 1u);
  EXPECT_FALSE(un[0].measured());
  EXPECT_EQ(un[0].direction.phiDeg, 200);
  test::expectErrorContaining([&] { parseDirectionList("81", dirs, "--lights"); },
                              {"--lights: item '81'", "81 light directions (0..80)"});
  test::expectErrorContaining([&] { parseDirectionList("5-2", dirs, "--views"); }, {"'5-2'", "empty range"});
  test::expectErrorContaining([&] { parseDirectionList("1,,2", dirs, "--views"); }, {"is empty"});
  test::expectErrorContaining([&] { parseDirectionList("t95p0", dirs, "--views"); },
                              {"'t95p0'", "view direction theta = 95"});
  test::expectErrorContaining([&] { parseDirectionList("tenp3", dirs, "--views"); }, {"not tTHETApPHI"});
  test::expectErrorContaining([&] { parseDirectionList("front", dirs, "--views"); }, {"'front'", "N-M"});
  EXPECT_EQ(parseImageSize("256x128", "--size"), (std::pair<int, int>{256, 128}));
  test::expectErrorContaining([] { parseImageSize("256", "--size"); }, {"--size: expected WxH"});
  test::expectErrorContaining([] { parseImageSize("0x5", "--size"); }, {"out of range"});
}

}  // namespace
}  // namespace nbtf
