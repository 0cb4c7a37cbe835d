#include "io/image_io.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "io/color.h"
#include "test_util.h"

namespace nbtf {
using test::expectErrorContaining;
using test::TempDir;

TEST(ImageIo, FormatsFromNames) {
  EXPECT_EQ(imageFormatFromName("a/b.JPG"), ImageFormat::Jpg);
  EXPECT_EQ(imageFormatFromName("x.jpeg"), ImageFormat::Jpg);
  EXPECT_EQ(imageFormatFromName("x.png"), ImageFormat::Png);
  EXPECT_EQ(imageFormatFromName("x.exr"), ImageFormat::Exr);
  expectErrorContaining([] { imageFormatFromName("x.tif"); }, {"x.tif", "extension"});
  expectErrorContaining([] { parseImageFormat("bmp"); }, {"bmp"});
}

TEST(ImageIo, PngRoundTripKeepsChannelOrder) {
  TempDir dir;
  Image8 img;
  img.width = 2, img.height = 1;
  img.rgb = {255, 0, 0, 0, 0, 255};  // red, blue
  writeImage8(dir / "a.png", ImageFormat::Png, img);
  Image8 back = readImage8(dir / "a.png");
  EXPECT_EQ(back.width, 2);
  EXPECT_EQ(back.rgb, img.rgb);
}

TEST(ImageIo, SrgbWriterEncodes) {
  TempDir dir;
  float lin[3] = {0.2158605f, 0.0f, 1.0f};
  writeImageSrgb8(dir / "a.png", ImageFormat::Png, 1, 1, lin);
  Image8 back = readImage8(dir / "a.png");
  EXPECT_EQ(back.rgb, (std::vector<std::uint8_t>{128, 0, 255}));
}

TEST(ImageIo, ExrHalfFloatAndXyzRoundTrip) {
  TempDir dir;
  std::vector<float> rgb = {0.1f, 0.5f, 2.0f, 0.0f, 0.25f, 0.75f};
  writeExr(dir / "f.exr", 2, 1, rgb.data(), /*half=*/false);
  EXPECT_EQ(readExr(dir / "f.exr").rgb, rgb);  // float32 is exact
  writeExr(dir / "x.exr", 2, 1, rgb.data(), /*half=*/true, ExrColorSpace::CieXyz);
  // The XYZ chromaticities in the header make the reader convert back, whatever the fallback.
  ImageF back = readExr(dir / "x.exr", ExrColorSpace::LinearSrgb);
  for (std::size_t i = 0; i < rgb.size(); ++i) EXPECT_NEAR(back.rgb[i], rgb[i], 3e-3f * (1 + rgb[i]));
}

TEST(ImageIo, WritesAreAtomicAndLeaveNoTemporaries) {
  TempDir dir;
  std::vector<float> rgb(12, 0.5f);
  writeImageSrgb8(dir / "a.jpg", ImageFormat::Jpg, 2, 2, rgb.data());
  writeExr(dir / "b.exr", 2, 2, rgb.data());
  int files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir.path())) {
    ++files;
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos);
  }
  EXPECT_EQ(files, 2);
}

TEST(ImageIo, WriteIntoMissingFolderFailsClearly) {
  std::vector<float> rgb(3, 0.5f);
  expectErrorContaining([&] { writeImageSrgb8("/nonexistent/dir/a.png", ImageFormat::Png, 1, 1, rgb.data()); },
                        {"/nonexistent/dir/a.png"});
  expectErrorContaining([&] { writeExr("/nonexistent/dir/a.exr", 1, 1, rgb.data()); }, {"/nonexistent/dir/a.exr"});
}

TEST(ImageIo, ReadErrorsNameTheFile) {
  TempDir dir;
  expectErrorContaining([&] { readImage8(dir / "missing.png"); }, {"missing.png", "cannot open"});
  std::ofstream(dir / "empty.jpg");
  expectErrorContaining([&] { readImage8(dir / "empty.jpg"); }, {"empty.jpg", "empty"});
  std::ofstream(dir / "bad.exr") << "not an exr";
  expectErrorContaining([&] { readExr(dir / "bad.exr"); }, {"bad.exr"});
}

}  // namespace nbtf
