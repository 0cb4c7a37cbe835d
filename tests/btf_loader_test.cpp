#include "io/btf_loader.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "io/btf_names.h"
#include "io/color.h"
#include "test_util.h"
#include "util/progress.h"

namespace nbtf {
namespace fs = std::filesystem;
using test::expectErrorContaining;
using test::TempDir;
using test::writeTestStack;

namespace {
const std::vector<Direction> kLights = {{0, 0}, {15, 0}, {15, 60}};
const std::vector<Direction> kViews = {{0, 0}, {30, 30}};

LoadOptions quiet() {
  LoadOptions o;
  o.progress = false;
  return o;
}

// Largest difference between the loaded stack and the pattern it was written from.
float maxPatternError(const BtfStack& s, int x0 = 0, int y0 = 0) {
  float worst = 0;
  for (int l = 0; l < s.numLights(); ++l)
    for (int v = 0; v < s.numViews(); ++v)
      for (int y = 0; y < s.height(); ++y)
        for (int x = 0; x < s.width(); ++x)
          for (int c = 0; c < 3; ++c) {
            float want = test::patternValue(l, v, x + x0, y + y0, c);
            float got = s.sample(s.imageIndex(l, v), y * s.width() + x, c);
            worst = std::max(worst, std::fabs(want - got));
          }
  return worst;
}
}  // namespace

TEST(BtfLoader, LoadsUbo2003ViewFolders) {
  TempDir dir;
  writeTestStack(dir.path(), kLights, kViews, 5, 4, Layout::Ubo2003, ImageFormat::Png);
  BtfStack s = loadBtfStack(dir.path(), quiet());
  EXPECT_EQ(s.layout, Layout::Ubo2003);
  EXPECT_EQ(s.numLights(), 3);
  EXPECT_EQ(s.numViews(), 2);
  EXPECT_EQ(s.width(), 5);
  EXPECT_EQ(s.height(), 4);
  EXPECT_EQ(s.sampleType(), SampleType::Srgb8);
  EXPECT_EQ(s.bytesInMemory(), 3u * 2 * 5 * 4 * 3);  // 8-bit stays 8-bit
  // 8-bit sRGB quantization: at most half a code step, ~0.5/255 * slope (<= 12.92 / 255 near 0... < 0.01 here).
  EXPECT_LT(maxPatternError(s), 0.01f);
  EXPECT_DOUBLE_EQ(s.lights()[2].phiDeg, 60);
}

TEST(BtfLoader, LoadsUtiaPngAndExr) {
  TempDir png, exr;
  writeTestStack(png.path(), kLights, kViews, 4, 3, Layout::Utia, ImageFormat::Png);
  writeTestStack(exr.path(), kLights, kViews, 4, 3, Layout::Utia, ImageFormat::Exr);
  BtfStack a = loadBtfStack(png.path(), quiet());
  EXPECT_EQ(a.layout, Layout::Utia);
  EXPECT_LT(maxPatternError(a), 0.01f);
  BtfStack b = loadBtfStack(exr.path(), quiet());
  EXPECT_EQ(b.sampleType(), SampleType::Half);
  // Stored as half CIE XYZ, converted back to linear sRGB: half precision (~1e-3 relative).
  EXPECT_LT(maxPatternError(b), 4e-3f);
}

TEST(BtfLoader, LoadsFlatFolderAndPrefixedNames) {
  TempDir dir;
  writeTestStack(dir.path(), kLights, kViews, 3, 3, Layout::Ubo2003, ImageFormat::Png, /*flat=*/true);
  // Rename to the prefixed underscore variant.
  for (const auto& e : fs::directory_iterator(dir.path())) {
    std::string name = e.path().filename().string();
    std::replace(name.begin(), name.end(), ' ', '_');
    fs::rename(e.path(), e.path().parent_path() / ("WoolPKNT256_" + name));
  }
  BtfStack s = loadBtfStack(dir.path(), quiet());
  EXPECT_EQ(s.layout, Layout::Ubo2003);
  EXPECT_EQ(s.numImages(), 6);
  EXPECT_LT(maxPatternError(s), 0.01f);
}

TEST(BtfLoader, ForcedLayoutWins) {
  TempDir dir;
  writeTestStack(dir.path(), kLights, kViews, 2, 2, Layout::Utia, ImageFormat::Png);
  LoadOptions o = quiet();
  o.layout = Layout::Ubo2003;
  EXPECT_EQ(loadBtfStack(dir.path(), o).layout, Layout::Ubo2003);
}

TEST(BtfLoader, CropIsAppliedWhileLoading) {
  TempDir dir;
  writeTestStack(dir.path(), kLights, kViews, 8, 6, Layout::Utia, ImageFormat::Png);
  LoadOptions o = quiet();
  o.crop = {2, 1, 3, 4};
  BtfStack s = loadBtfStack(dir.path(), o);
  EXPECT_EQ(s.width(), 3);
  EXPECT_EQ(s.height(), 4);
  EXPECT_EQ(s.sourceWidth, 8);
  EXPECT_EQ(s.bytesInMemory(), 6u * 3 * 4 * 3);
  EXPECT_LT(maxPatternError(s, 2, 1), 0.01f);
  o.crop = {6, 0, 3, 2};
  expectErrorContaining([&] { loadBtfStack(dir.path(), o); }, {"crop", "outside", "8 x 6"});
}

// The input is resolved once: its listing, crop and shape, and the stack loaded from that
// description is the stack loaded from the path.
TEST(BtfLoader, AResolvedInputDescribesTheLoadAndLoadsTheSameStack) {
  TempDir dir;
  writeTestStack(dir.path(), kLights, kViews, 8, 6, Layout::Utia, ImageFormat::Png);
  LoadOptions o = quiet();
  o.crop = {2, 1, 3, 4};
  const BtfInput in = resolveBtfInput(dir.path(), o);
  EXPECT_EQ(in.listing.layout, Layout::Utia);
  EXPECT_EQ(in.listing.files.size(), 6u);
  EXPECT_TRUE(in.cropped);
  EXPECT_EQ(in.crop.x, 2);
  EXPECT_EQ(in.sourceWidth, 8);
  EXPECT_EQ(in.sourceHeight, 6);
  EXPECT_EQ(in.shape.width, 3);
  EXPECT_EQ(in.shape.height, 4);
  EXPECT_EQ(in.shape.images(), 6);
  EXPECT_EQ(in.shape.type, SampleType::Srgb8);
  EXPECT_EQ(in.ubo2014, nullptr);
  const BtfStack fromInput = loadBtfStack(in, o), fromPath = loadBtfStack(dir.path(), o);
  EXPECT_EQ(fromInput.width(), 3);
  EXPECT_EQ(fromInput.crop.x, 2);
  EXPECT_EQ(fromInput.sourceWidth, 8);
  for (int i = 0; i < fromInput.numImages(); ++i)
    for (int t = 0; t < fromInput.numTexels(); ++t)
      for (int c = 0; c < 3; ++c) ASSERT_EQ(fromInput.sample(i, t, c), fromPath.sample(i, t, c));
  EXPECT_LT(maxPatternError(fromInput, 2, 1), 0.01f);
  o.crop = {6, 0, 3, 2};
  expectErrorContaining([&] { resolveBtfInput(dir.path(), o); }, {dir.path(), "crop", "outside", "8 x 6"});
  o.crop = {};
  const BtfInput whole = resolveBtfInput(dir.path(), o);
  EXPECT_FALSE(whole.cropped);
  EXPECT_EQ(whole.crop.width, 8);
  EXPECT_TRUE(loadBtfStack(whole, o).crop.empty());
}

TEST(BtfLoader, AbrdfAndImageAccessAgree) {
  TempDir dir;
  writeTestStack(dir.path(), kLights, kViews, 3, 2, Layout::Utia, ImageFormat::Png);
  BtfStack s = loadBtfStack(dir.path(), quiet());
  std::vector<float> abrdf = s.abrdfLinear(4);
  std::vector<float> image(s.numTexels() * 3);
  for (int i = 0; i < s.numImages(); ++i) {
    s.imageLinear(i, image.data());
    for (int c = 0; c < 3; ++c) EXPECT_EQ(abrdf[3 * i + c], image[4 * 3 + c]);
  }
}

// ---- Bad input: every case names the file and the problem.

TEST(BtfLoaderErrors, MissingPath) {
  expectErrorContaining([] { loadBtfStack("/nonexistent/stack", quiet()); }, {"/nonexistent/stack", "no such"});
}

TEST(BtfLoaderErrors, EmptyFolder) {
  TempDir dir;
  expectErrorContaining([&] { loadBtfStack(dir.path(), quiet()); }, {dir.path(), "empty"});
}

TEST(BtfLoaderErrors, FolderOfUnrelatedFiles) {
  TempDir dir;
  std::ofstream(dir / "notes.txt") << "hello";
  std::ofstream(dir / "data.csv") << "1,2";
  expectErrorContaining([&] { loadBtfStack(dir.path(), quiet()); }, {dir.path(), "no BTF images"});
}

TEST(BtfLoaderErrors, MissingImage) {
  TempDir dir;
  auto paths = writeTestStack(dir.path(), kLights, kViews, 2, 2, Layout::Utia, ImageFormat::Png);
  fs::remove(paths[3]);  // light 1, view 1
  expectErrorContaining([&] { loadBtfStack(dir.path(), quiet()); },
                        {"incomplete", "1 of 6", "theta 15, phi 0", "theta 30, phi 30", "tv030_pv030"});
}

TEST(BtfLoaderErrors, DuplicatedAngles) {
  TempDir dir;
  auto paths = writeTestStack(dir.path(), kLights, kViews, 2, 2, Layout::Ubo2003, ImageFormat::Png);
  // Same angles under another running index.
  fs::path copy = fs::path(paths[0]).parent_path() / ubo2003FileName(99, kLights[0], kViews[0], ".png");
  fs::copy_file(paths[0], copy);
  expectErrorContaining([&] { loadBtfStack(dir.path(), quiet()); }, {"duplicate", "00099"});
}

TEST(BtfLoaderErrors, UnparseableName) {
  TempDir dir;
  auto paths = writeTestStack(dir.path(), kLights, kViews, 2, 2, Layout::Utia, ImageFormat::Png);
  fs::path bad = fs::path(paths[0]).parent_path() / "snapshot.png";
  fs::copy_file(paths[0], bad);
  expectErrorContaining([&] { loadBtfStack(dir.path(), quiet()); }, {"snapshot.png", "does not parse"});
  fs::remove(bad);
  fs::copy_file(paths[0], fs::path(paths[0]).parent_path() / "tl000_pl000_tv000.png");
  expectErrorContaining([&] { loadBtfStack(dir.path(), quiet()); }, {"tl000_pl000_tv000.png", "pv"});
}

TEST(BtfLoaderErrors, TruncatedJpegAndPng) {
  for (ImageFormat f : {ImageFormat::Jpg, ImageFormat::Png}) {
    TempDir dir;
    auto paths = writeTestStack(dir.path(), kLights, kViews, 16, 16, Layout::Utia, f);
    auto size = fs::file_size(paths[4]);
    fs::resize_file(paths[4], size / 2);
    expectErrorContaining([&] { loadBtfStack(dir.path(), quiet()); }, {paths[4], "truncated"});
  }
}

TEST(BtfLoaderErrors, GarbageImage) {
  TempDir dir;
  auto paths = writeTestStack(dir.path(), kLights, kViews, 4, 4, Layout::Utia, ImageFormat::Png);
  std::ofstream(paths[2], std::ios::trunc) << "this is not a png";
  expectErrorContaining([&] { loadBtfStack(dir.path(), quiet()); }, {paths[2], "not a PNG"});
}

TEST(BtfLoaderErrors, SizeMismatch) {
  TempDir dir, other;
  auto paths = writeTestStack(dir.path(), kLights, kViews, 4, 4, Layout::Utia, ImageFormat::Png);
  auto big = writeTestStack(other.path(), kLights, kViews, 5, 4, Layout::Utia, ImageFormat::Png);
  fs::copy_file(big[5], paths[5], fs::copy_options::overwrite_existing);
  expectErrorContaining([&] { loadBtfStack(dir.path(), quiet()); }, {paths[5], "5 x 4", "4 x 4"});
}

TEST(BtfLoaderErrors, GrayscaleAnd16BitAmongColour) {
  TempDir dir;
  auto paths = writeTestStack(dir.path(), kLights, kViews, 4, 4, Layout::Utia, ImageFormat::Png);
  cv::imwrite(paths[1], cv::Mat(4, 4, CV_8UC1, cv::Scalar(100)));
  expectErrorContaining([&] { loadBtfStack(dir.path(), quiet()); }, {paths[1], "grayscale"});
  cv::imwrite(paths[1], cv::Mat(4, 4, CV_16UC3, cv::Scalar(1000, 1000, 1000)));
  expectErrorContaining([&] { loadBtfStack(dir.path(), quiet()); }, {paths[1], "16-bit"});
}

TEST(BtfLoaderErrors, ExrWithNanOrNegativeIsRejected) {
  TempDir dir;
  auto paths = writeTestStack(dir.path(), kLights, kViews, 3, 3, Layout::Utia, ImageFormat::Exr);
  std::vector<float> rgb(27, 0.5f);
  rgb[4] = std::nanf("");
  writeExr(paths[2], 3, 3, rgb.data(), true, ExrColorSpace::LinearSrgb);
  expectErrorContaining([&] { loadBtfStack(dir.path(), quiet()); }, {paths[2], "nan", "rejected"});
  rgb[4] = -1;
  writeExr(paths[2], 3, 3, rgb.data(), true, ExrColorSpace::LinearSrgb);
  expectErrorContaining([&] { loadBtfStack(dir.path(), quiet()); }, {paths[2], "-1", "non-negative"});
  rgb[4] = INFINITY;
  writeExr(paths[2], 3, 3, rgb.data(), false, ExrColorSpace::LinearSrgb);
  expectErrorContaining([&] { loadBtfStack(dir.path(), quiet()); }, {paths[2], "inf"});
}

TEST(BtfLoaderErrors, TruncatedExr) {
  TempDir dir;
  auto paths = writeTestStack(dir.path(), kLights, kViews, 16, 16, Layout::Utia, ImageFormat::Exr);
  fs::resize_file(paths[3], fs::file_size(paths[3]) - 40);
  expectErrorContaining([&] { loadBtfStack(dir.path(), quiet()); }, {paths[3]});
}

TEST(BtfLoaderErrors, MixedFormats) {
  TempDir dir, other;
  auto paths = writeTestStack(dir.path(), kLights, kViews, 3, 3, Layout::Utia, ImageFormat::Png);
  auto exr = writeTestStack(other.path(), kLights, kViews, 3, 3, Layout::Utia, ImageFormat::Exr);
  fs::remove(paths[5]);
  fs::copy_file(exr[5], fs::path(paths[5]).replace_extension(".exr"));
  expectErrorContaining([&] { loadBtfStack(dir.path(), quiet()); }, {"mixed formats"});
}

TEST(BtfLoader, LoadsFull81x81Hemisphere) {
  TempDir dir;
  writeTestStack(dir.path(), hemisphere81(), hemisphere81(), 2, 2, Layout::Ubo2003, ImageFormat::Png);
  BtfStack s = loadBtfStack(dir.path(), quiet());
  ASSERT_EQ(s.numImages(), 6561);
  for (int i = 0; i < 81; ++i) {
    EXPECT_EQ(s.lights()[i], hemisphere81()[i]);
    EXPECT_EQ(s.views()[i], hemisphere81()[i]);
  }
  EXPECT_LT(maxPatternError(s), 0.01f);
}

}  // namespace nbtf

namespace nbtf {
namespace {

// A decode's staging folder is refused as an interrupted decode even when the kill came before
// its description was written (an empty folder, or the description's temporary only).
TEST(BtfLoader, ADecodeStagingFolderIsAnInterruptedDecodeEvenBeforeItsDescription) {
  test::TempDir dir;
  const std::string staging = dir / (std::string(".out") + kDecodeStagingSuffix);
  std::filesystem::create_directories(staging);
  for (const std::string& path : {staging, staging + "/"})
    test::expectErrorContaining([&] { listBtfStack(path); }, {".out.nbtf-decoding", "interrupted nbtf decode"});
  // A visible folder of that name is someone's stack, not ours.
  const std::string visible = dir / (std::string("out") + kDecodeStagingSuffix);
  std::filesystem::create_directories(visible);
  EXPECT_EQ(test::errorOf([&] { listBtfStack(visible); }).find("interrupted"), std::string::npos);
}

}  // namespace
}  // namespace nbtf
