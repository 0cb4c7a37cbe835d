// The names a decode gives its images (pipeline/decoded_image_names.cpp), per layout, for measured and unmeasured directions.
#include "pipeline/decoded_image_names.h"

#include <gtest/gtest.h>

#include "pipeline/decode_selection.h"
#include "test_util.h"
#include "util/error.h"

namespace nbtf {
namespace {

TEST(DecodedImageNames, MeasuredImagesAreNumberedByTheSourceImage) {
  const DirectionChoice light{{15, 60}, 2}, view{{30, 30}, 1};
  // Image number light x views + view: 2 x 3 + 1.
  EXPECT_EQ(decodedImagePath(Layout::Ubo2003, ImageFormat::Jpg, light, view, 3),
            "tv030_pv030/00007 tl015 pl060 tv030 pv030.jpg");
  EXPECT_EQ(decodedImagePath(Layout::Utia, ImageFormat::Png, light, view, 3), "tv030_pv030/tl015_pl060_tv030_pv030.png");
  // An output index, when given, numbers the image instead.
  EXPECT_EQ(decodedImagePath(Layout::Ubo2003, ImageFormat::Png, light, view, 3, 0),
            "tv030_pv030/00000 tl015 pl060 tv030 pv030.png");
}

TEST(DecodedImageNames, UnmeasuredDirectionsNeedTheOutputIndexInUbo2003) {
  const DirectionChoice measured{{0, 0}, 0}, unmeasured{{37.5, 200}, -1};
  EXPECT_FALSE(unmeasured.measured());
  const std::string ubo = decodedImagePath(Layout::Ubo2003, ImageFormat::Png, unmeasured, measured, 9, 12);
  EXPECT_EQ(ubo.rfind("tv000_pv000/00012 ", 0), 0u) << ubo;
  test::expectErrorContaining([&] { decodedImagePath(Layout::Ubo2003, ImageFormat::Png, measured, unmeasured, 9); },
                              {"needs the output index"});
  // UTIA names carry the angles only: no index needed.
  const std::string utia = decodedImagePath(Layout::Utia, ImageFormat::Exr, measured, unmeasured, 9);
  EXPECT_EQ(utia.find(".exr"), utia.size() - 4) << utia;
  EXPECT_EQ(utia.find('/'), utia.rfind('/')) << utia;  // one view folder
}

}  // namespace
}  // namespace nbtf
