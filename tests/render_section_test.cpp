// A rendered comparison read back for the evaluation report (eval/render_section.cpp): the folder `nbtf render --compare` writes.
#include "eval/render_section.h"

#include <gtest/gtest.h>

#include <vector>

#include "io/image_io.h"
#include "render/compare.h"
#include "test_util.h"
#include "util/atomic_file.h"

namespace nbtf {
namespace {

// The folder as `nbtf render --compare` writes it: compare.json and three 4 x 2 PNGs.
void writeCompareFolder(const test::TempDir& dir) {
  RenderComparison c;
  c.all.rmse = 0.02, c.dark.rmse = 0.005, c.bright.rmse = 0.04;
  CompareReportInfo info;
  info.reference = "ref.nbtf", info.compressed = "small.nbtf", info.scene = "sphere";
  info.width = 4, info.height = 2, info.sampling = "adaptive, 2 levels", info.magnify = 8;
  writeFileAtomic(dir / "compare.json", compareJson(c, info));
  std::vector<float> rgb(4 * 2 * 3);
  for (std::size_t i = 0; i < rgb.size(); ++i) rgb[i] = static_cast<float>(i) / rgb.size();
  for (const char* name : {"reference.png", "compressed.png", "error.png"})
    writeImageSrgb8(dir / name, ImageFormat::Png, 4, 2, rgb.data());
}

TEST(RenderSection, ReadsWhatRenderCompareWrites) {
  test::TempDir dir;
  writeCompareFolder(dir);
  const RenderSection s = loadRenderSection(dir.path());
  EXPECT_TRUE(s.present());
  EXPECT_EQ(s.folder, dir.path());
  EXPECT_EQ(s.scene, "sphere");
  EXPECT_EQ(s.sampling, "adaptive, 2 levels");
  EXPECT_EQ(s.reference, "ref.nbtf");
  EXPECT_EQ(s.compressed, "small.nbtf");
  EXPECT_EQ(s.space, "linear RGB radiance");
  EXPECT_EQ(s.width, 4);
  EXPECT_EQ(s.height, 2);
  EXPECT_EQ(s.rmseAll, 0.02);
  EXPECT_EQ(s.rmseDark, 0.005);
  EXPECT_EQ(s.rmseBright, 0.04);
  EXPECT_EQ(s.errorMagnification, 8);
  for (const Image8* image : {&s.referenceImage, &s.compressedImage, &s.errorImage}) {
    EXPECT_EQ(image->width, 4);
    EXPECT_EQ(image->height, 2);
    EXPECT_EQ(image->rgb.size(), 4u * 2 * 3);
  }
  EXPECT_FALSE(RenderSection{}.present());
}

TEST(RenderSection, MissingFilesAndKeysAreNamed) {
  test::TempDir dir;
  test::expectErrorContaining([&] { loadRenderSection(dir.path()); },
                              {"compare.json", "cannot open", "nbtf render --compare"});
  writeFileAtomic(dir / "compare.json", std::string(R"({"scene": "sphere"})"));
  test::expectErrorContaining([&] { loadRenderSection(dir.path()); }, {"compare.json", "not a render comparison"});
  writeFileAtomic(dir / "compare.json", std::string("{"));
  test::expectErrorContaining([&] { loadRenderSection(dir.path()); }, {"compare.json", "not a render comparison"});
  writeCompareFolder(dir);
  std::filesystem::remove(dir / "error.png");
  test::expectErrorContaining([&] { loadRenderSection(dir.path()); }, {"error.png"});
}

}  // namespace
}  // namespace nbtf
