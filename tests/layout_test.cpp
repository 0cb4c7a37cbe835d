// How a stack is laid out and sampled (util/layout.h): layout and sample type names, `--layout` and `--crop` text.
#include "util/layout.h"

#include <gtest/gtest.h>

#include "test_util.h"
#include "util/error.h"

namespace nbtf {

TEST(BtfStack, ParseCropAndLayout) {
  Crop c = parseCrop("10,20,100,50");
  EXPECT_EQ(c.x, 10);
  EXPECT_EQ(c.height, 50);
  EXPECT_THROW(parseCrop("10,20,100"), Error);
  EXPECT_THROW(parseCrop("10,20,0,5"), Error);
  EXPECT_THROW(parseCrop("-1,0,5,5"), Error);
  EXPECT_EQ(parseLayout("utia"), Layout::Utia);
  EXPECT_EQ(parseLayout("ubo2014"), Layout::Ubo2014);  // a Bonn .btf file
  EXPECT_EQ(layoutName(Layout::Ubo2014), "ubo2014");
  EXPECT_THROW(parseLayout("ubo2015"), Error);
}

TEST(Layout, NamesReadBackAndBadTextIsNamed) {
  for (Layout l : {Layout::Ubo2003, Layout::Utia, Layout::Ubo2014}) EXPECT_EQ(parseLayout(layoutName(l)), l);
  EXPECT_EQ(parseLayout("ubo"), Layout::Ubo2003);  // the short name
  EXPECT_EQ(layoutName(Layout::Unknown), "unknown");
  test::expectErrorContaining([] { parseLayout("UTIA"); }, {"unknown layout 'UTIA'", "ubo2003, utia or ubo2014"});
  EXPECT_EQ(sampleTypeName(SampleType::Srgb8), "8-bit sRGB");
  EXPECT_EQ(sampleTypeName(SampleType::Half), "half float (linear)");
}

TEST(Layout, CropTextIsFourNonNegativeIntegers) {
  const Crop c = parseCrop(" 0, 7 ,3,4");
  EXPECT_EQ(c, (Crop{0, 7, 3, 4}));
  EXPECT_FALSE(c.empty());
  EXPECT_TRUE(Crop{}.empty());
  test::expectErrorContaining([] { parseCrop("1,2,3,x"); }, {"--crop: expected X,Y,W,H (integers), got '1,2,3,x'"});
  test::expectErrorContaining([] { parseCrop("1,2,3,4,5"); }, {"expected X,Y,W,H"});
  test::expectErrorContaining([] { parseCrop("1.5,2,3,4"); }, {"expected X,Y,W,H"});
  test::expectErrorContaining([] { parseCrop("0,0,3000000000,4"); }, {"3000000000", "is too large (at most 2147483647)"});
  test::expectErrorContaining([] { parseCrop("0,0,1234567890123456789,4"); }, {"is too large"});
  test::expectErrorContaining([] { parseCrop("0,0,5,-2"); }, {"must have X,Y >= 0 and W,H > 0"});
}

}  // namespace nbtf
