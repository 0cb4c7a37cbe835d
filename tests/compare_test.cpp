// The comparison metrics (render/compare.h): whole image, darkest and brightest 10% of the material's pixels.
#include <gtest/gtest.h>

#include <cmath>

#include "render/compare.h"
#include "util/error.h"

namespace nbtf {
namespace {

TEST(RenderCompare, DarkAndBrightRegionsByReferenceLuminance) {
  const int W = 10, H = 10;
  std::vector<float> ref(3 * W * H), test, coverage(W * H, 1.0f);
  for (int p = 0; p < W * H; ++p) ref[3 * p] = ref[3 * p + 1] = ref[3 * p + 2] = 0.01f * p;  // a ramp
  test = ref;
  for (int p = 0; p < 10; ++p) test[3 * p] += 0.3f;            // error on the darkest 10 pixels (red only)
  for (int p = 90; p < 100; ++p) test[3 * p + 2] -= 0.03f;     // a smaller one on the brightest 10
  coverage[50] = 0;                                             // off the material: not in any region
  const RenderComparison c = compareImages(ref, test, coverage, W, H);
  EXPECT_EQ(c.dark.pixels, 10u);
  EXPECT_EQ(c.bright.pixels, 10u);
  EXPECT_NEAR(c.dark.rmse, std::sqrt(0.09 / 3), 1e-6);
  EXPECT_NEAR(c.bright.rmse, std::sqrt(0.0009 / 3), 1e-6);
  EXPECT_NEAR(c.all.rmse, std::sqrt((10 * 0.09 + 10 * 0.0009) / 300), 1e-6);
  EXPECT_NEAR(c.maxAbsError, 0.3, 1e-6);
  EXPECT_NEAR(c.darkMaxLuminance, 0.09, 1e-6);
}

TEST(RenderCompare, ErrorImageAndReports) {
  const std::vector<float> a = {0.5f, 0.5f, 0.5f}, b = {0.4f, 0.5f, 0.7f};
  const std::vector<float> e = errorImage(a, b, 8);
  EXPECT_NEAR(e[0], 0.8, 1e-6);
  EXPECT_NEAR(e[2], 1.6, 1e-6);
  const RenderComparison c = compareImages(a, b, {1.0f}, 1, 1);
  CompareReportInfo info;
  info.scene = "sphere";
  const std::string md = compareMarkdown(c, info), json = compareJson(c, info);
  EXPECT_NE(md.find("darkest 10%"), std::string::npos);
  EXPECT_NE(json.find("\"dark10\""), std::string::npos);
  EXPECT_THROW(compareImages(a, {0.1f}, {1.0f}, 1, 1), Error);
}

}  // namespace
}  // namespace nbtf
