// `nbtf export-gltf` end to end (gltf/gltf_export.h): from an image stack with its ground truth
// and from a .nbtf; deterministic with its seed; bad input refused with nothing written.
#include "gltf/gltf_export.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "codec/nbtf_file.h"
#include "decoder_fixtures.h"
#include "gltf/gltf_read.h"
#include "synth/synth_material.h"
#include "synth/synth_ubo2014.h"
#include "test_util.h"

namespace nbtf::gltf {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

std::string synthStack(const std::string& name) {
  const std::string dir = test::tempFilePath(name);
  if (fs::exists(fs::path(dir) / "ground_truth")) return dir;
  fs::remove_all(dir);
  synth::SynthOptions o;
  o.preset = "glossy";
  o.width = o.height = 8;
  o.seed = 4;
  o.layout = Layout::Utia;
  o.format = ImageFormat::Png;
  o.progress = false;
  synth::writeSynthStack(o, dir);
  return dir;
}

ExportOptions quick() {
  ExportOptions o;
  o.progress = false;
  o.fit.samples = 128;
  o.fit.iterations = 10;
  return o;
}

std::string fileText(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

json report(const std::string& dir) {
  std::ifstream in(fs::path(dir) / kFitReportName);
  return json::parse(in);
}

TEST(GltfExport, AStackWithItsGroundTruthIsMeasuredAgainstBothAndTheSameSeedGivesTheSameFiles) {
  const std::string stack = synthStack("gltf_export_stack");
  const std::string a = test::tempFilePath("gltf_export_a"), b = test::tempFilePath("gltf_export_b");
  fs::remove_all(a), fs::remove_all(b);
  const ExportSummary s = exportGltf(stack, a, quick());
  exportGltf(stack, b, quick());
  EXPECT_EQ(s.width, 8);
  EXPECT_EQ(s.images, 81 * 81);
  ASSERT_EQ(s.errors.size(), 2u);
  EXPECT_EQ(s.errors[0].name, "stack");
  EXPECT_EQ(s.errors[1].name, "ground_truth");
  for (const FitError& e : s.errors) {
    EXPECT_GT(e.rmse, 0);
    EXPECT_LT(e.rmse, 0.5);
    EXPECT_EQ(e.byLight.size(), 6u);  // the rings 0, 15, ..., 75
  }
  const json r = report(a);
  EXPECT_EQ(r["rmse"]["stack"]["rmse"].get<double>(), s.errors[0].rmse);
  EXPECT_EQ(r["texture_bytes"]["total"].get<std::size_t>(), s.bytes.total());
  EXPECT_EQ(r["exposure"].get<double>(), s.exposure);
  for (const char* f : {"base_color.png", "metallic_roughness.png", "normal.png", "material.gltf", "meshes.bin"})
    EXPECT_EQ(fileText(fs::path(a) / f), fileText(fs::path(b) / f)) << f;
  // What the export wrote reads back, and its error is what the report says (measured on
  // the textures, not on the fit's own numbers).
  const GltfMaterial m = readGltfMaterial((fs::path(a) / kGltfFileName).string());
  EXPECT_EQ(m.width, 8);
  EXPECT_EQ(m.exposure, s.exposure);
}

TEST(GltfExport, ANbtfFileIsFittedThroughItsDecoderAndMeasuredAgainstIt) {
  const std::string file = test::tempFilePath("gltf_export.nbtf"), out = test::tempFilePath("gltf_export_nbtf");
  fs::remove_all(out);
  writeNbtf(file, testing::makeSmoothMaterial(3, 4, 3));
  const ExportSummary s = exportGltf(file, out, quick());
  ASSERT_EQ(s.errors.size(), 1u);
  EXPECT_EQ(s.errors[0].name, "nbtf");
  EXPECT_EQ(s.width, 4);
  ExportOptions o = quick();
  o.reference = synthStack("gltf_export_stack");  // 8 x 8: not the file's stack
  test::expectErrorContaining([&] { exportGltf(file, out + "2", o); }, {o.reference, "is not the stack"});
  o = quick();
  o.crop = Crop{0, 0, 2, 2};
  test::expectErrorContaining([&] { exportGltf(file, out + "2", o); }, {"--crop applies to image stacks"});
  EXPECT_FALSE(fs::exists(out + "2"));
}

TEST(GltfExport, AUbo2014FileGoesThroughTheSamePath) {
  const std::string btf = test::tempFilePath("gltf_export.btf"), out = test::tempFilePath("gltf_export_ubo2014");
  fs::remove_all(out);
  synth::SynthOptions so;
  so.width = so.height = 8, so.render.supersampling = 1, so.progress = false;
  Ubo2014FactorizeOptions f;
  f.components = 16;
  synth::writeSynthUbo2014(so, btf, f);
  ExportOptions o = quick();
  o.sheen = o.specular = ExtensionMode::Off;
  const ExportSummary s = exportGltf(btf, out, o);
  EXPECT_EQ(s.images, 151 * 151);
  ASSERT_EQ(s.errors.size(), 1u);  // the file itself; a .btf has no ground truth beside it
  EXPECT_GT(s.errors[0].rmse, 0);
  EXPECT_LT(s.errors[0].rmse, 0.5);
  EXPECT_TRUE(fs::exists(fs::path(out) / kGltfFileName));
}

TEST(GltfExport, TheCommandRefusesBadInputWithNothingWritten) {
  const std::string bad = test::tempFilePath("gltf_export_bad"), out = test::tempFilePath("gltf_export_bad_out");
  fs::remove_all(bad), fs::remove_all(out);
  fs::create_directories(fs::path(bad) / "tv000_pv000");
  std::ofstream(fs::path(bad) / "tv000_pv000" / "00000 tl000 pl000 tv000 pv000.jpg") << "not a jpeg";
  test::RunResult r = test::runNbtf("export-gltf '" + bad + "' -o '" + out + "' -q");
  EXPECT_NE(r.exitCode, 0);
  EXPECT_NE(r.output.find(bad), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
  r = test::runNbtf("export-gltf '" + synthStack("gltf_export_stack") + "' -o '" + out + "' -q --samples 64 --iterations 3");
  EXPECT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("RMSE vs ground_truth"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(fs::path(out) / "material.gltf"));
  r = test::runNbtf("export-gltf '" + synthStack("gltf_export_stack") + "' -o '" + out + "' -q --samples 2");
  EXPECT_NE(r.exitCode, 0);
  EXPECT_NE(r.output.find("--samples"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace nbtf::gltf
