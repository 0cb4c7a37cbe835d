// `nbtf eval` end to end: a .nbtf file and its reference stack on disk -> report files whose
// RMSE is the direct computation; a reference of another material is rejected with a clear
// error and a non-zero exit, writing no report.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "io/source_fingerprint.h"
#include "codec_fixtures.h"
#include "eval/compressed_source.h"
#include "io/btf_loader.h"
#include "io/ground_truth.h"
#include "io/image_io.h"
#include "test_util.h"
#include "util/progress.h"

namespace nbtf {
namespace {

struct CommandRun {
  int code = -1;
  std::string output;
};

// Runs `nbtf <args>` and captures stdout + stderr.
CommandRun runNbtf(const std::string& args, const std::string& logPath) {
  std::string cmd = std::string(NBTF_BIN_DIR) + "/nbtf " + args + " > '" + logPath + "' 2>&1";
  CommandRun r;
  int status = std::system(cmd.c_str());
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream in(logPath);
  std::stringstream s;
  s << in.rdbuf();
  r.output = s.str();
  return r;
}

class CmdEval : public ::testing::Test {
 protected:
  void SetUp() override {
    Progress::setQuiet(true);
    if (!std::filesystem::exists(std::string(NBTF_BIN_DIR) + "/nbtf")) GTEST_SKIP() << "nbtf binary not built";
    btf = testing::makeBtf(3, 4, 3);
    file = tmp / "m.nbtf";
    writeNbtf(file, btf);
    // The source images are larger than the file's crop (3,5,4,3), as for a real material.
    test::writeTestStack(tmp / "ref", btf.lights, btf.views, btf.sourceWidth, btf.sourceHeight, Layout::Utia,
                         ImageFormat::Exr);
  }
  test::TempDir tmp;
  CompressedBtf btf;
  std::string file;
};

TEST_F(CmdEval, WritesAReportWhoseRmseIsTheDirectComputation) {
  CommandRun r = runNbtf("eval '" + file + "' --reference '" + (tmp / "ref") + "' -o '" + (tmp / "out") + "' -q --threads 2",
                  tmp / "log");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("linear RGB / alpha"), std::string::npos) << r.output;
  for (const char* f : {"report.md", "report.html", "report.json", "rmse_heatmap.png"})
    EXPECT_TRUE(std::filesystem::exists(tmp / ("out/" + std::string(f)))) << f;
  std::ifstream in(tmp / "out/report.json");
  nlohmann::json j = nlohmann::json::parse(in);

  // Direct: load with the file's crop, decode, pool squared errors over everything.
  LoadOptions load;
  load.crop = btf.crop;
  load.progress = false;
  BtfStack ref = loadBtfStack(tmp / "ref", load);
  CompressedReconstruction rec(btf);
  std::vector<float> a(static_cast<std::size_t>(ref.numTexels()) * 3), b(a.size());
  double sum = 0, held = 0;
  for (int i = 0; i < ref.numImages(); ++i) {
    ref.imageLinear(i, a.data());
    rec.image(i, b.data());
    double s = 0;
    for (std::size_t k = 0; k < a.size(); ++k) s += std::pow((double(a[k]) - b[k]) / btf.alpha, 2);
    sum += s;
    if (i == 1 || i == 4) held += s;  // the fixture's hold-out images
  }
  EXPECT_NEAR(j["rmse"].get<double>(), std::sqrt(sum / (a.size() * ref.numImages())), 1e-9);
  EXPECT_NEAR(j["rmse_holdout"].get<double>(), std::sqrt(held / (a.size() * 2)), 1e-9);
  EXPECT_EQ(j["material"]["alpha"].get<double>(), btf.alpha);
  EXPECT_EQ(j["bytes"]["file"].get<std::uint64_t>(), std::filesystem::file_size(file));
  EXPECT_EQ(j["compressed"].get<std::string>(), file);
}

TEST_F(CmdEval, PcaFileGivesAReportWithItsSizeParts) {
  CompressedBtf pca = testing::makePcaBtf(3, 4, 3);  // the fixture's geometry, crop and directions
  std::string pcaFile = tmp / "p.nbtf";
  writeNbtf(pcaFile, pca);
  CommandRun r = runNbtf("eval '" + pcaFile + "' --reference '" + (tmp / "ref") + "' -o '" + (tmp / "pout") + "' -q",
                         tmp / "log");
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream in(tmp / "pout/report.json");
  nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j["method"], "PCA, C = 3");
  EXPECT_EQ(j["method_family"], "pca");
  EXPECT_EQ(j["method_parameter"], 3);
  for (const char* key : {"pca_mean", "pca_basis", "pca_coefficients", "total", "raw_float32", "file"})
    EXPECT_TRUE(j["bytes"].contains(key)) << key;
  EXPECT_EQ(j["bytes"]["pca_basis"].get<std::uint64_t>(), 6u * 3 * 3 * 4);
  EXPECT_EQ(j["bytes"]["file"].get<std::uint64_t>(), std::filesystem::file_size(pcaFile));
  // The RMSE is that of mean + coefficients x basis against the reference.
  LoadOptions load;
  load.crop = pca.crop;
  load.progress = false;
  BtfStack ref = loadBtfStack(tmp / "ref", load);
  double sse = 0;
  for (int i = 0; i < ref.numImages(); ++i)
    for (int t = 0; t < ref.numTexels(); ++t)
      for (int c = 0; c < 3; ++c) sse += std::pow(testing::pcaValue(pca, t, i, c) - ref.sample(i, t, c) / pca.alpha, 2);
  EXPECT_NEAR(j["rmse"].get<double>(), std::sqrt(sse / (3.0 * ref.numTexels() * ref.numImages())), 1e-6);
  std::ifstream md(tmp / "pout/report.md");
  std::stringstream text;
  text << md.rdbuf();
  EXPECT_NE(text.str().find("PCA basis"), std::string::npos);
  EXPECT_NE(text.str().find("PCA coefficients"), std::string::npos);
  // A sweep reads it as a point of the PCA curve.
  CommandRun s = runNbtf("eval --summarize -o '" + (tmp / "sweep") + "' '" + (tmp / "pout/report.json") + "'", tmp / "log2");
  ASSERT_EQ(s.code, 0) << s.output;
  EXPECT_TRUE(std::filesystem::exists(tmp / "sweep/rd_ref_pca.dat")) << s.output;
}

// The stack's own distance from the float ground truth (the noise floor) is printed and
// reported only where a ground truth lies beside the stack.
TEST_F(CmdEval, ReportsTheNoiseFloorWithAGroundTruthAndOmitsItWithout) {
  auto evalReport = [&](const std::string& name, CommandRun& run) {
    run = runNbtf("eval '" + file + "' --reference '" + (tmp / "ref") + "' -o '" + (tmp / name) + "' -q --threads 2",
                  tmp / (name + ".log"));
    std::ifstream in(tmp / (name + "/report.json"));
    return nlohmann::json::parse(in);
  };
  CommandRun bare;
  nlohmann::json without = evalReport("bare", bare);
  ASSERT_EQ(bare.code, 0) << bare.output;
  EXPECT_EQ(bare.output.find("noise floor"), std::string::npos) << bare.output;
  EXPECT_TRUE(without["rmse_reference_vs_ground_truth"].is_null());
  EXPECT_TRUE(without["noise_floor_cause"].is_null());

  // A ground truth 0.01 above the stack's values everywhere (one float32 EXR per view, the
  // light images stacked): the floor is 0.01 / alpha, up to the stack's half rounding.
  const float offset = 0.01f;
  const int w = btf.sourceWidth, h = btf.sourceHeight, lights = static_cast<int>(btf.lights.size());
  std::filesystem::create_directories(tmp / ("ref/" + std::string(kGroundTruthFolder)));
  for (std::size_t v = 0; v < btf.views.size(); ++v) {
    std::vector<float> rgb(static_cast<std::size_t>(w) * h * lights * 3);
    for (int l = 0; l < lights; ++l)
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
          for (int c = 0; c < 3; ++c)
            rgb[((static_cast<std::size_t>(l) * h + y) * w + x) * 3 + c] = test::patternValue(l, int(v), x, y, c) + offset;
    writeExr(groundTruthPath(tmp / "ref", btf.views[v]), w, h * lights, rgb.data(), false);
  }
  CommandRun truth;
  nlohmann::json with = evalReport("truth", truth);
  ASSERT_EQ(truth.code, 0) << truth.output;
  EXPECT_NE(truth.output.find("noise floor"), std::string::npos) << truth.output;
  EXPECT_NE(truth.output.find("half float stack"), std::string::npos) << truth.output;
  EXPECT_NE(truth.output.find("vs truth RMSE"), std::string::npos) << truth.output;
  const double floor = offset / btf.alpha;
  EXPECT_NEAR(with["rmse_reference_vs_ground_truth"].get<double>(), floor, 0.05 * floor);
  EXPECT_NEAR(with["rmse_reference_vs_ground_truth_holdout"].get<double>(), floor, 0.05 * floor);
  EXPECT_EQ(with["reference_encoding"].get<std::string>(), "half float");
  EXPECT_EQ(with["noise_floor_cause"].get<std::string>(), "half-precision rounding");
  EXPECT_FALSE(with["rmse_ground_truth_holdout"].is_null());
  // The stack-side figures do not change with a ground truth beside it.
  EXPECT_EQ(with["rmse"].get<double>(), without["rmse"].get<double>());
  std::ifstream md(tmp / "truth/report.md");
  std::stringstream text;
  text << md.rdbuf();
  EXPECT_NE(text.str().find("Noise floor: the stack (half float)"), std::string::npos);
}

TEST_F(CmdEval, RejectsAReferenceWithOtherDirections) {
  auto views = btf.views;
  views[1] = {30, 60};
  test::writeTestStack(tmp / "other", btf.lights, views, btf.sourceWidth, btf.sourceHeight, Layout::Utia,
                       ImageFormat::Exr);
  CommandRun r = runNbtf("eval '" + file + "' --reference '" + (tmp / "other") + "' -o '" + (tmp / "out") + "' -q",
                  tmp / "log");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.output.find("does not match"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("view direction 1 is (30\xC2\xB0, 60\xC2\xB0) in the reference"), std::string::npos)
      << r.output;
  EXPECT_FALSE(std::filesystem::exists(tmp / "out/report.json"));
}

TEST_F(CmdEval, RejectsAReferenceOfAnotherSize) {
  CommandRun r = runNbtf("eval '" + file + "' --reference '" + (tmp / "ref") + "' --crop 0,0,5,3 -o '" + (tmp / "out") +
                      "' -q",
                  tmp / "log");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.output.find("texel size is 5 x 3 in the reference but 4 x 3 in the file"), std::string::npos)
      << r.output;
}

// Another material with the same size and directions used to pass silently: the file's
// source fingerprint (per-image mean linear RGB) now stops it, unless --force, which the
// report states. 8-bit and float loadings of one material match; so does the file's crop.
TEST_F(CmdEval, AnotherMaterialIsRejectedByTheSourceFingerprint) {
  LoadOptions load;
  load.crop = btf.crop;
  load.progress = false;
  CompressedBtf withFp = btf;
  withFp.metadataJson = R"({"source": {"fingerprint": )" +
                        sourceFingerprintJson(sourceFingerprint(loadBtfStack(tmp / "ref", load))) + "}}";
  const std::string fpFile = tmp / "fp.nbtf";
  writeNbtf(fpFile, withFp);
  auto reportOf = [&](const std::string& dir) {
    return nlohmann::json::parse(std::ifstream((std::filesystem::path(tmp / dir) / "report.json").string()));
  };

  CommandRun same = runNbtf("eval '" + fpFile + "' --reference '" + (tmp / "ref") + "' -o '" + (tmp / "a") + "' -q",
                            tmp / "log");
  ASSERT_EQ(same.code, 0) << same.output;
  EXPECT_EQ(same.output.find("warning"), std::string::npos) << same.output;
  EXPECT_NE(reportOf("a")["details"]["reference check"].get<std::string>().find("matches"), std::string::npos)
      << same.output;

  // The same material as 8-bit PNGs: quantized, still the same material.
  test::writeTestStack(tmp / "ref8", btf.lights, btf.views, btf.sourceWidth, btf.sourceHeight, Layout::Utia,
                       ImageFormat::Png);
  CommandRun eight = runNbtf("eval '" + fpFile + "' --reference '" + (tmp / "ref8") + "' -o '" + (tmp / "b") + "' -q",
                             tmp / "log");
  EXPECT_EQ(eight.code, 0) << eight.output;

  // Another material: same size and directions, other values.
  std::vector<float> rgb(static_cast<std::size_t>(btf.sourceWidth) * btf.sourceHeight * 3);
  for (std::size_t l = 0; l < btf.lights.size(); ++l)
    for (std::size_t v = 0; v < btf.views.size(); ++v) {
      for (std::size_t i = 0; i < rgb.size(); ++i) rgb[i] = 0.3f * (1.0f - test::patternValue(int(l), int(v), int(i / 3) % btf.sourceWidth, int(i / 3) / btf.sourceWidth, int(i % 3)));
      auto folder = std::filesystem::path(tmp / "wool") / viewFolderName(btf.views[v]);
      std::filesystem::create_directories(folder);
      writeExr((folder / utiaFileName(btf.lights[l], btf.views[v], ".exr")).string(), btf.sourceWidth,
               btf.sourceHeight, rgb.data(), true, ExrColorSpace::CieXyz);
    }
  CommandRun other = runNbtf("eval '" + fpFile + "' --reference '" + (tmp / "wool") + "' -o '" + (tmp / "c") + "' -q",
                             tmp / "log");
  EXPECT_EQ(other.code, 1) << other.output;
  EXPECT_NE(other.output.find("is not the material"), std::string::npos) << other.output;
  EXPECT_NE(other.output.find("--force"), std::string::npos) << other.output;
  EXPECT_FALSE(std::filesystem::exists(tmp / "c/report.json"));

  CommandRun forced = runNbtf("eval '" + fpFile + "' --reference '" + (tmp / "wool") + "' -o '" + (tmp / "d") +
                                  "' -q --force",
                              tmp / "log");
  ASSERT_EQ(forced.code, 0) << forced.output;
  EXPECT_NE(forced.output.find("using it anyway (--force)"), std::string::npos) << forced.output;
  EXPECT_NE(reportOf("d")["details"]["reference check"].get<std::string>().find("MISMATCH"), std::string::npos);

  // An older file without a fingerprint: a warning, and the evaluation goes on.
  CommandRun old = runNbtf("eval '" + file + "' --reference '" + (tmp / "ref") + "' -o '" + (tmp / "e") + "' -q",
                           tmp / "log");
  EXPECT_EQ(old.code, 0) << old.output;
  EXPECT_NE(old.output.find("has no source fingerprint"), std::string::npos) << old.output;
}

// Missing parent folders of -o are created, as decode and compress do.
TEST_F(CmdEval, CreatesMissingParentFoldersOfTheReport) {
  CommandRun r = runNbtf("eval '" + file + "' --reference '" + (tmp / "ref") + "' -o '" + (tmp / "a/b/c") + "' -q",
                         tmp / "log");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(std::filesystem::exists(tmp / "a/b/c/report.json"));
}

// A file name with commas is one file (cxxopts would split a list option's value at them).
TEST_F(CmdEval, AFileNameWithCommasIsOneFile) {
  const std::string commas = tmp / "a,b,c.nbtf";
  std::filesystem::copy_file(file, commas);
  CommandRun r = runNbtf("eval '" + commas + "' --reference '" + (tmp / "ref") + "' -o '" + (tmp / "r") + "' -q",
                         tmp / "log");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(std::filesystem::exists(tmp / "r/report.json"));
}

TEST_F(CmdEval, MissingOptionsAreNamed) {
  CommandRun r = runNbtf("eval '" + file + "' -o '" + (tmp / "out") + "'", tmp / "log");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.output.find("missing --reference"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace nbtf

namespace nbtf {
namespace {

// Two captures of one kind of material (nbtf-synth's corduroy, seeds 1 and 2: the closest
// pair measured, pattern difference 0.44) have the same per-image means within 1.1%: the
// texel pattern tells them apart, while the capture itself matches (0.004).
TEST(EvalFingerprint, AnotherCaptureOfTheSameKindOfMaterialIsRefused) {
  test::TempDir dir;
  for (const char* seed : {"1", "2"}) {
    const test::RunResult synth = test::runProgram(
        "nbtf-synth", std::string("--preset corduroy --size 16x16 --layout ubo2003 --no-ground-truth -q --seed ") + seed +
                          " -o '" + (dir / (std::string("c") + seed)) + "'");
    ASSERT_EQ(synth.exitCode, 0) << synth.output;
  }
  const std::string file = dir / "c1.nbtf";
  test::RunResult r = test::runNbtf("compress '" + (dir / "c1") + "' -o '" + file + "' --clusters 8 --epochs 1 -q");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  r = test::runNbtf("eval '" + file + "' --reference '" + (dir / "c1") + "' -o '" + (dir / "r1") + "' -q");
  EXPECT_EQ(r.exitCode, 0) << r.output;
  r = test::runNbtf("eval '" + file + "' --reference '" + (dir / "c2") + "' -o '" + (dir / "r2") + "' -q");
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("the means agree"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("but the texels do not: texel pattern difference"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "r2"));
  // --summarize takes report.json files: a folder is named as such, and a refused summary
  // leaves no output folder.
  r = test::runNbtf("eval --summarize -o '" + (dir / "sweep") + "' '" + (dir / "r1") + "'");
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("is a folder, expected a report.json file"), std::string::npos) << r.output;
  r = test::runNbtf("eval --summarize -o '" + (dir / "sweep") + "' '" + (dir / "r1/report.json") + "' '" +
                    (dir / "r1/report.json") + "'");
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "sweep")) << r.output;
}

}  // namespace
}  // namespace nbtf
