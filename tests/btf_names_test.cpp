#include "io/btf_names.h"

#include <gtest/gtest.h>

#include "io/btf_loader.h"
#include "util/error.h"

namespace nbtf {

TEST(BtfNames, ParsesUbo2003SpaceSeparated) {
  auto p = parseBtfFileName("00008 tl000 pl000 tv030 pv030.jpg");
  ASSERT_TRUE(p);
  EXPECT_EQ(p->layout, Layout::Ubo2003);
  EXPECT_EQ(p->index, 8);
  EXPECT_DOUBLE_EQ(p->light.thetaDeg, 0);
  EXPECT_DOUBLE_EQ(p->view.thetaDeg, 30);
  EXPECT_DOUBLE_EQ(p->view.phiDeg, 30);
}

TEST(BtfNames, ParsesUbo2003PrefixedUnderscoreVariant) {
  auto p = parseBtfFileName("WoolPKNT256_00084_tl015_pl000_tv015_pv120.jpg");
  ASSERT_TRUE(p);
  EXPECT_EQ(p->layout, Layout::Ubo2003);
  EXPECT_EQ(p->index, 84);
  EXPECT_DOUBLE_EQ(p->light.thetaDeg, 15);
  EXPECT_DOUBLE_EQ(p->light.phiDeg, 0);
  EXPECT_DOUBLE_EQ(p->view.thetaDeg, 15);
  EXPECT_DOUBLE_EQ(p->view.phiDeg, 120);
}

TEST(BtfNames, ParsesUtia) {
  auto p = parseBtfFileName("tl075_pl345_tv060_pv018.png");
  ASSERT_TRUE(p);
  EXPECT_EQ(p->layout, Layout::Utia);
  EXPECT_EQ(p->index, -1);
  EXPECT_DOUBLE_EQ(p->light.thetaDeg, 75);
  EXPECT_DOUBLE_EQ(p->light.phiDeg, 345);
  EXPECT_DOUBLE_EQ(p->view.thetaDeg, 60);
  EXPECT_DOUBLE_EQ(p->view.phiDeg, 18);
  // Shifted (non-integer) angles are taken as they are.
  auto s = parseBtfFileName("tl017.500_pl000_tv015_pv000.exr");
  ASSERT_TRUE(s);
  EXPECT_DOUBLE_EQ(s->light.thetaDeg, 17.5);
}

TEST(BtfNames, UnrelatedNameIsNotABtfName) {
  EXPECT_FALSE(parseBtfFileName("README.png"));
  EXPECT_FALSE(parseBtfFileName("thumbnail.jpg"));
}

TEST(BtfNames, PartialOrOutOfRangeNamesAreErrors) {
  EXPECT_THROW(parseBtfFileName("tl000_pl000_tv030.png"), Error);
  EXPECT_THROW(parseBtfFileName("tl095_pl000_tv030_pv000.png"), Error);
  EXPECT_THROW(parseBtfFileName("tl030_pl360_tv030_pv000.png"), Error);
}

TEST(BtfNames, WrittenNamesParseBack) {
  Direction l{45, 20}, v{75, 345};
  auto u = parseBtfFileName(ubo2003FileName(1234, l, v, ".jpg"));
  ASSERT_TRUE(u);
  EXPECT_EQ(u->index, 1234);
  EXPECT_EQ(u->light, l);
  EXPECT_EQ(u->view, v);
  auto t = parseBtfFileName(utiaFileName(l, v, ".png"));
  ASSERT_TRUE(t);
  EXPECT_EQ(t->light, l);
  EXPECT_EQ(t->view, v);
  EXPECT_EQ(viewFolderName(v), "tv075_pv345");
  EXPECT_EQ(ubo2003FileName(8, {0, 0}, {30, 30}, ".jpg"), "00008 tl000 pl000 tv030 pv030.jpg");
}

}  // namespace nbtf
