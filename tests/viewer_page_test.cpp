// The `nbtf view` page (shader/viewer_page.cpp): the embedded decoder, the reference images and their directions, base64.
#include "shader/viewer_page.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>

#include "shader/shader_export.h"
#include "shader_test_materials.h"
#include "test_util.h"
#include "util/directions.h"

namespace nbtf {
namespace {

using testing::makeShaderClusteredMaterial;
using testing::makeShaderPerTexelMaterial;
using testing::readText;

TEST(ViewerPage, EmbedsTheDecoderAndRefusesALargeReference) {
  const CompressedBtf m = makeShaderClusteredMaterial();
  const ShaderDecoder s = buildShaderDecoder(m, "cl.nbtf");
  const std::string page = buildViewerPage(s, m, {});
  EXPECT_NE(page.find("<canvas id=\"view\""), std::string::npos);
  EXPECT_NE(page.find("nbtf_decode"), std::string::npos);
  EXPECT_EQ(page.find("http://"), std::string::npos);  // nothing fetched
  EXPECT_EQ(page.find("https://"), std::string::npos);
  EXPECT_EQ(page.find("@NBTF_DATA@"), std::string::npos);
  EXPECT_NE(page.find(base64Encode(s.textures[0].data.data(), 63)), std::string::npos);
  EXPECT_NE(page.find(base64Encode(s.uniformBlocks[0].data.data(), 63)), std::string::npos);
  ViewerReference big;
  big.name = "stack";
  big.width = 2048, big.height = 1024;
  big.lights = std::vector<Direction>(9), big.views = std::vector<Direction>(1);
  big.srgb.resize(static_cast<std::size_t>(2048) * 1024 * 3 * 9);
  ViewerOptions o;
  o.reference = &big;
  test::expectErrorContaining([&] { buildViewerPage(s, m, o); }, {"stack", "9 images", "MiB", "48"});
  ViewerReference small = big;
  small.width = 9, small.height = 7;
  small.srgb.assign(9 * 7 * 3 * 9, 128);
  o.reference = &small;
  EXPECT_NE(buildViewerPage(s, m, o).find("\"reference\":{"), std::string::npos);
}

// The embedded subset: every pair while it fits, else the same share of the lights and the
// views, spread over the hemisphere; at 100 x 100 texels 40 of UBO2003's 81 each.
TEST(ViewerPage, AReferenceTooLargeForThePageEmbedsDirectionsSpreadOverTheHemisphere) {
  const std::vector<Direction>& dirs = hemisphere81();
  const ViewerReferenceSelection small = viewerReferenceDirections(dirs, dirs, 16 * 16);
  EXPECT_EQ(small.lights.size(), 81u);
  EXPECT_EQ(small.views.size(), 81u);
  const ViewerReferenceSelection full = viewerReferenceDirections(dirs, dirs, 100 * 100);
  EXPECT_EQ(full.lights.size(), 40u);
  EXPECT_EQ(full.views.size(), 40u);
  EXPECT_LE(full.lights.size() * full.views.size() * 100 * 100 * 3, kMaxViewerReferenceBytes);
  EXPECT_TRUE(std::is_sorted(full.lights.begin(), full.lights.end()));
  // Spread: the normal is kept, and no measured direction is more than 25 degrees from a kept one.
  EXPECT_EQ(dirs[full.lights.front()].thetaDeg, 0);
  for (const Direction& d : dirs) {
    double nearest = 180;
    for (int i : full.lights) {
      const auto a = d.unitVector(), b = dirs[i].unitVector();
      nearest = std::min(nearest, std::acos(std::min(1.0, a[0] * b[0] + a[1] * b[1] + a[2] * b[2])) * 180 / M_PI);
    }
    EXPECT_LT(nearest, 25) << d.thetaDeg << ", " << d.phiDeg;
  }
  test::expectErrorContaining([&] { viewerReferenceDirections(dirs, dirs, std::size_t(1) << 30); },
                              {"one image", "MiB", "--crop"});
}

// The reference must be the file's material, checked as nbtf eval checks it.
TEST(ViewerPage, AnotherMaterialsStackIsRefusedUnlessForced) {
  test::TempDir tmp;
  for (const char* preset : {"wool", "corduroy"}) {
    const auto synth = test::runProgram("nbtf-synth", std::string("--preset ") + preset +
                                                          " --size 8x8 --layout ubo2003 --no-ground-truth -q --seed 1 -o " +
                                                          tmp / preset);
    ASSERT_EQ(synth.exitCode, 0) << synth.output;
  }
  const std::string file = tmp / "wool.nbtf";
  ASSERT_EQ(test::runNbtf("compress " + tmp / "wool" + " -o " + file + " --method pca --components 2 -q").exitCode, 0);
  const auto wrong = test::runNbtf("view " + file + " -o " + tmp / "w.html --reference " + tmp / "corduroy" + " -q");
  EXPECT_EQ(wrong.exitCode, 1) << wrong.output;
  EXPECT_NE(wrong.output.find("is not the material"), std::string::npos) << wrong.output;
  EXPECT_NE(wrong.output.find("--force"), std::string::npos) << wrong.output;
  EXPECT_FALSE(std::filesystem::exists(tmp / "w.html"));
  const auto forced = test::runNbtf("view " + file + " -o " + tmp / "w.html --reference " + tmp / "corduroy" + " --force -q");
  ASSERT_EQ(forced.exitCode, 0) << forced.output;
  EXPECT_NE(forced.output.find("using it anyway (--force)"), std::string::npos) << forced.output;
  EXPECT_NE(readText(tmp / "w.html").find("\"fingerprint\":\"MISMATCH"), std::string::npos);
  const auto right = test::runNbtf("view " + file + " -o " + tmp / "r.html --reference " + tmp / "wool" + " -q");
  ASSERT_EQ(right.exitCode, 0) << right.output;
  EXPECT_NE(readText(tmp / "r.html").find("\"fingerprint\":\"matches"), std::string::npos);
}

// The paper's 100 x 100 texels with its reference: the page is written, with a subset.
TEST(ViewerPage, AHundredByHundredMaterialWithItsReferenceFitsThePage) {
  test::TempDir tmp;
  const auto synth = test::runProgram(
      "nbtf-synth", "--preset fabric --size 100x100 --layout ubo2003 --no-ground-truth -q --seed 1 -o " + tmp / "fabric");
  ASSERT_EQ(synth.exitCode, 0) << synth.output;
  const std::string file = tmp / "fabric.nbtf";
  ASSERT_EQ(test::runNbtf("compress " + tmp / "fabric" + " -o " + file + " --method pca --components 2 -q").exitCode, 0);
  const auto r = test::runNbtf("view " + file + " -o " + tmp / "page.html --reference " + tmp / "fabric");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("reference: 40 of 81 lights x 40 of 81 views embedded"), std::string::npos) << r.output;
  const std::string page = readText(tmp / "page.html");
  EXPECT_NE(page.find("\"measured_lights\":81"), std::string::npos);
  EXPECT_LT(page.size(), std::size_t(70) << 20);  // 48 MiB of images as base64, and the page
}

TEST(ViewerPage, CommandEmbedsTheReferenceStackAtTheFilesCrop) {
  test::TempDir tmp;
  const CompressedBtf m = makeShaderPerTexelMaterial();  // 8 x 6 texels cropped at (3, 5) of 18 x 26
  const std::string file = tmp / "pt.nbtf", stack = tmp / "stack";
  writeNbtf(file, m);
  test::writeTestStack(stack, m.lights, m.views, m.sourceWidth, m.sourceHeight, Layout::Utia, ImageFormat::Png);
  const auto r = test::runNbtf("view " + file + " -o " + tmp / "new/page.html --reference " + stack + " -q");
  ASSERT_EQ(r.exitCode, 0) << r.output;  // missing folders above the page are created
  const std::string page = readText(tmp / "new/page.html");
  EXPECT_NE(page.find("\"reference\":{"), std::string::npos);
  EXPECT_NE(page.find("\"width\":8"), std::string::npos);
  // The wrong crop: refused, naming both sizes, and no page written.
  const auto bad = test::runNbtf("view " + file + " -o " + tmp / "bad.html --reference " + stack + " --crop 0,0,4,4 -q");
  EXPECT_EQ(bad.exitCode, 1) << bad.output;
  EXPECT_NE(bad.output.find("4 x 4"), std::string::npos) << bad.output;
  EXPECT_FALSE(std::filesystem::exists(tmp / "bad.html"));
  // --crop without --reference is a mistake, said so.
  const auto stray = test::runNbtf("view " + file + " -o " + tmp / "x.html --crop 0,0,4,4");
  EXPECT_EQ(stray.exitCode, 1);
  EXPECT_NE(stray.output.find("--reference"), std::string::npos) << stray.output;
}

TEST(ViewerPage, Base64) {
  EXPECT_EQ(base64Encode("", 0), "");
  EXPECT_EQ(base64Encode("f", 1), "Zg==");
  EXPECT_EQ(base64Encode("fo", 2), "Zm8=");
  EXPECT_EQ(base64Encode("foo", 3), "Zm9v");
  EXPECT_EQ(base64Encode("foobar", 6), "Zm9vYmFy");
  const unsigned char high[] = {0xff, 0xfe, 0x80};
  EXPECT_EQ(base64Encode(high, 3), "//6A");
}

}  // namespace
}  // namespace nbtf
