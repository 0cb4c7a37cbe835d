// `nbtf render` end to end: a render of a .nbtf with its refined mask and statistics,
// --compare against the material's own decoded stack, and clear errors with exit status 1.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "codec/decoder.h"
#include "gltf/gltf_export.h"
#include "pipeline/decoder_output.h"
#include "codec_fixtures.h"
#include "decoder_fixtures.h"
#include "io/image_io.h"
#include "test_util.h"

namespace nbtf {
namespace {

namespace fs = std::filesystem;

struct CliRun {
  int status = -1;
  std::string out, err;
};

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

CliRun runNbtf(const std::string& args, const test::TempDir& dir) {
  const std::string out = dir / "stdout.txt", err = dir / "stderr.txt";
  const std::string cmd = std::string("'") + NBTF_BIN_DIR + "/nbtf' " + args + " >'" + out + "' 2>'" + err + "'";
  const int raw = std::system(cmd.c_str());
  return {WIFEXITED(raw) ? WEXITSTATUS(raw) : -1, slurp(out), slurp(err)};
}

class RenderCli : public ::testing::Test {
 protected:
  void SetUp() override {
    material = testing::makeSmoothMaterial(3, 6, 4);
    file = dir / "m.nbtf";
    writeNbtf(file, material);
  }
  test::TempDir dir;
  CompressedBtf material;
  std::string file;
};

TEST_F(RenderCli, RendersPngExrMaskAndStats) {
  const std::string png = dir / "a.png", exr = dir / "a.exr", mask = dir / "mask.png", stats = dir / "s.json";
  const CliRun r = runNbtf("render '" + file + "' -o '" + png + "' --exr '" + exr + "' --scene cloth --size 48x36 --tiling 2 "
                        "--show-refined '" + mask + "' --stats-json '" + stats + "' --ray-cost --threads 2 -q", dir);
  ASSERT_EQ(r.status, 0) << r.err;
  const Image8 img = readImage8(png);
  EXPECT_EQ(img.width, 48);
  EXPECT_EQ(img.height, 36);
  EXPECT_EQ(readExr(exr).width, 48);
  EXPECT_EQ(readImage8(mask).height, 36);
  const nlohmann::json j = nlohmann::json::parse(slurp(stats));
  EXPECT_GT(j["derivative_rays"].get<double>(), 0);
  EXPECT_GT(j["refined_fraction"].get<double>(), 0);
  EXPECT_LT(j["refined_fraction"].get<double>(), 1);
  // --ray-cost is a timing: the test checks that it was measured, not what it measured
  // (a loaded machine can make either kind of ray the slower one); scripts/bench_render.sh
  // reports the figure.
  EXPECT_GT(j["ray_cost"]["samples"].get<double>(), 0);
  for (const char* key : {"plain_seconds", "derivative_seconds", "derivative_over_plain"})
    EXPECT_TRUE(j["ray_cost"].contains(key)) << key;
  // The same scene, uniform, against the first render as a reference.
  const CliRun u = runNbtf("render '" + file + "' -o '" + (dir / "u.png") + "' --scene cloth --size 48x36 --tiling 2 --uniform 3 "
                        "--reference '" + exr + "' --stats-json '" + stats + "' -q", dir);
  ASSERT_EQ(u.status, 0) << u.err;
  const double rmse = nlohmann::json::parse(slurp(stats))["rmse_vs_reference"].get<double>();
  EXPECT_GT(rmse, 0);
  EXPECT_LT(rmse, 0.05);
}

TEST_F(RenderCli, CompareWithItsDecodedStack) {
  const std::string stack = dir / "stack";
  NbtfDecoder dec(material);
  DecodeStackOptions o;
  o.format = ImageFormat::Exr;
  o.progress = false;
  writeDecodedStack(dec, stack, o);
  const std::string out = dir / "cmp";
  const CliRun r = runNbtf("render --compare '" + stack + "' '" + file + "' -o '" + out + "' --scene plane --size 40x30 -q", dir);
  ASSERT_EQ(r.status, 0) << r.err;
  for (const char* f : {"reference.png", "compressed.png", "error.png", "reference.exr", "compare.md", "compare.json"})
    EXPECT_TRUE(fs::exists(fs::path(out) / f)) << f;
  // Swapped arguments are a clear error.
  const CliRun swapped = runNbtf("render --compare '" + file + "' '" + stack + "' -o '" + out + "' -q", dir);
  EXPECT_EQ(swapped.status, 1);
  EXPECT_NE(swapped.err.find("expected the original image stack folder"), std::string::npos) << swapped.err;
  const nlohmann::json j = nlohmann::json::parse(slurp((fs::path(out) / "compare.json").string()));
  EXPECT_LT(j["rmse"]["all"]["rmse"].get<double>(), 0.02);
  EXPECT_GT(j["rmse"]["dark10"]["pixels"].get<int>(), 0);
}

// --also: a glTF fit of the same stack rendered beside the .nbtf, and the three side by side.
TEST_F(RenderCli, CompareShowsAGltfFitBesideTheNbtf) {
  const std::string stack = dir / "stack_also";
  NbtfDecoder dec(material);
  DecodeStackOptions o;
  o.format = ImageFormat::Exr;
  o.progress = false;
  writeDecodedStack(dec, stack, o);
  gltf::ExportOptions eo;
  eo.progress = false, eo.fit.samples = 64, eo.fit.iterations = 5;
  const std::string gltfDir = dir / "fit";
  gltf::exportGltf(stack, gltfDir, eo);
  const std::string out = dir / "cmp_also", gltfFile = gltfDir + "/material.gltf";
  const CliRun r = runNbtf("render --compare '" + stack + "' '" + file + "' --also '" + gltfFile + "' -o '" + out +
                               "' --scene tile --size 40x30 -q",
                           dir);
  ASSERT_EQ(r.status, 0) << r.err;
  for (const char* f : {"compressed.png", "also.png", "also_error.png", "compare_also.md", "compare_also.json"})
    EXPECT_TRUE(fs::exists(fs::path(out) / f)) << f;
  const Image8 row = readImage8((fs::path(out) / "side_by_side.png").string());
  EXPECT_EQ(row.width, 120);
  EXPECT_EQ(row.height, 30);
  const nlohmann::json j = nlohmann::json::parse(slurp((fs::path(out) / "compare_also.json").string()));
  EXPECT_GT(j["rmse"]["all"]["rmse"].get<double>(), 0);
  // The glTF file alone is a material too; --also without --compare is an error.
  EXPECT_EQ(runNbtf("render '" + gltfFile + "' -o '" + (dir / "g.png") + "' --scene tile --size 20x15 -q", dir).status, 0);
  const CliRun bad = runNbtf("render '" + file + "' --also '" + gltfFile + "' -o '" + (dir / "y.png") + "' -q", dir);
  EXPECT_EQ(bad.status, 1);
  EXPECT_NE(bad.err.find("--also is for --compare"), std::string::npos) << bad.err;
}

TEST_F(RenderCli, ClearErrors) {
  CliRun r = runNbtf("render '" + (dir / "missing.nbtf") + "' -o '" + (dir / "x.png") + "' -q", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("missing.nbtf: no such file"), std::string::npos) << r.err;
  r = runNbtf("render '" + file + "' -o '" + (dir / "x.png") + "' --scene teapot -q", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("unknown scene 'teapot'"), std::string::npos) << r.err;
  r = runNbtf("render '" + file + "' -o '" + (dir / "x.png") + "' --spp 5 -q", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("--spp"), std::string::npos) << r.err;
  r = runNbtf("render '" + file + "' -o '" + (dir / "x.png") + "' --uniform 3 --adaptive -q", dir);
  EXPECT_EQ(r.status, 1);
  r = runNbtf("render '" + file + "' -o '" + (dir / "x.bmp") + "' -q", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("x.bmp"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "x.png"));
}

}  // namespace
}  // namespace nbtf

namespace nbtf {
namespace {

// --compare refuses a stack measured at other directions (eval's check), and every
// output's missing folders are made, with a clear error where a file is in the way.
TEST(RenderCliChecks, CompareNeedsTheSameDirectionsAndOutputsGetTheirFolders) {
  test::TempDir dir;
  const std::string file = dir / "m.nbtf";
  writeNbtf(file, testing::makeSmoothMaterial(3, 6, 4));  // the 81-direction hemisphere
  const std::string stack = testing::writeTestStack(dir / "stack");  // 9 x 9 directions
  CliRun r = runNbtf("render --compare '" + stack + "' '" + file + "' -o '" + (dir / "cmp") + "' --size 8x6 -q", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("does not match"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("the reference has 9 light directions, the file 81"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "cmp"));
  r = runNbtf("render '" + file + "' -o '" + (dir / "new/deep/a.png") + "' --stats-json '" + (dir / "other/s.json") +
                  "' --size 8x6 -q",
              dir);
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir / "new/deep/a.png"));
  EXPECT_TRUE(fs::exists(dir / "other/s.json"));
  r = runNbtf("render '" + file + "' -o '" + file + "/a.png' --size 8x6 -q", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("'" + file + "' is a file, not a folder"), std::string::npos) << r.err;
  // The size limit its message states is the one it checks.
  r = runNbtf("render '" + file + "' -o '" + (dir / "b.png") + "' --size 20000x10 -q", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("1 .. 16384 per side"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace nbtf
