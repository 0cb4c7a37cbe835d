// Sweep summaries: report.json -> entries, the Table 2 layout, rate-distortion data and a
// plot drawn by nbtf.
#include "eval/sweep.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "test_util.h"
#include "util/atomic_file.h"

namespace nbtf {
namespace {

using nlohmann::json;

SweepEntry entry(const std::string& material, const std::string& family, double parameter, double ratio, double rmse) {
  SweepEntry e;
  e.material = material, e.family = family, e.parameter = parameter, e.ratio = ratio, e.rmse = rmse;
  e.method = family == "clustered-neural" ? "clustered neural, k = " + std::to_string(int(parameter)) : family;
  e.rmseSrgb8 = rmse * 255, e.rmseHoldout = std::nan(""), e.blurSigma = 0.7;
  e.report = material + "/" + e.method + "/report.json";
  return e;
}

std::vector<SweepEntry> sample() {
  return {entry("WOOL", "clustered-neural", 1000, 4633, 0.0274), entry("WOOL", "per-texel-neural", NAN, 1885, 0.0264),
          entry("WOOL", "clustered-neural", 500, 5127, 0.0275), entry("fabric02", "clustered-neural", 500, 5127, 0.0212),
          entry("fabric02", "per-texel-neural", NAN, 1885, 0.0203)};
}

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(Sweep, ReadsTheKeysOfAReport) {
  json j = {{"material", {{"name", "WOOL"}}}, {"method", "clustered neural, k = 500"},
            {"method_family", "clustered-neural"}, {"method_parameter", 500}, {"ratio", 5127.5}, {"rmse", 0.0275},
            {"rmse_srgb8", 5.5}, {"rmse_holdout", nullptr}, {"blur_sigma", 0.8}};
  SweepEntry e = sweepEntryFromReport(j, "r.json");
  EXPECT_EQ(e.material, "WOOL");
  EXPECT_EQ(e.parameter, 500);
  EXPECT_EQ(e.ratio, 5127.5);
  EXPECT_TRUE(std::isnan(e.rmseHoldout));
  json noRatio = j;
  noRatio["ratio"] = nullptr;
  test::expectErrorContaining([&] { sweepEntryFromReport(noRatio, "r.json"); }, {"r.json", "compression ratio"});
  json noRmse = j;
  noRmse.erase("rmse");
  test::expectErrorContaining([&] { sweepEntryFromReport(noRmse, "r.json"); }, {"r.json", "missing key 'rmse'"});
  noRmse["rmse"] = "0.1";
  test::expectErrorContaining([&] { sweepEntryFromReport(noRmse, "r.json"); }, {"'rmse' is not a number"});
}

TEST(Sweep, TableHasMaterialsAsRowsAndMethodsAsColumns) {
  std::string md = sweepTablesMarkdown(sample());
  // Columns: the per-texel baseline first, then k ascending.
  EXPECT_NE(md.find("| material | per-texel-neural | clustered neural, k = 500 | clustered neural, k = 1000 |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| WOOL | 0.0264 | 0.0275 | 0.0274 |"), std::string::npos) << md;
  EXPECT_NE(md.find("| fabric02 | 0.0203 | 0.0212 | - |"), std::string::npos) << md;
  EXPECT_NE(md.find("| WOOL | 1 : 1885 | 1 : 5127 | 1 : 4633 |"), std::string::npos) << md;
  EXPECT_EQ(md.find("held-out"), std::string::npos) << "no hold-out table without hold-out results";
  auto dup = sample();
  dup.push_back(dup[0]);
  test::expectErrorContaining([&] { sweepTablesMarkdown(dup); }, {"two reports", "WOOL", "k = 1000"});
}

TEST(Sweep, WritesDataSortedByRatioAndDrawsThePlot) {
  test::TempDir tmp;
  SweepFiles f = writeSweepSummary(sample(), tmp / "sweep");
  EXPECT_EQ(f.dataFiles.size(), 4u);
  std::string wool = slurp(tmp / "sweep/rd_WOOL_clustered-neural.dat");
  EXPECT_LT(wool.find("4633 0.0274"), wool.find("5127 0.0275")) << wool;
  EXPECT_NE(wool.find("\"k=500\""), std::string::npos);
  EXPECT_NE(slurp(f.table).find("## Sweep"), std::string::npos);
  // One PNG per material, drawn by nbtf itself: no script, no external program.
  ASSERT_EQ(f.plots.size(), 2u);
  for (const auto& plot : f.plots) {
    auto drawn = readFileBytes(plot);
    ASSERT_GT(drawn.size(), 1000u) << plot;
    EXPECT_EQ(drawn[1], 'P') << plot;
  }
  EXPECT_FALSE(std::filesystem::exists(tmp / "sweep/rd_WOOL.gp"));
}

TEST(Sweep, PcaIsTheFirstCurveLabelledByComponents) {
  test::TempDir tmp;
  std::vector<SweepEntry> e = sample();
  for (int c : {16, 4}) {
    SweepEntry p = entry("WOOL", "pca", c, 500.0 / c, 0.08 / std::sqrt(c));
    p.method = "PCA, C = " + std::to_string(c);
    e.push_back(p);
  }
  std::string md = sweepTablesMarkdown(e);
  EXPECT_NE(md.find("| material | PCA, C = 4 | PCA, C = 16 | per-texel-neural |"), std::string::npos) << md;
  EXPECT_NE(md.find("PCA: mean + basis + coefficients"), std::string::npos) << md;
  SweepFiles f = writeSweepSummary(e, tmp / "sweep");
  std::string dat = slurp(tmp / "sweep/rd_WOOL_pca.dat");
  EXPECT_NE(dat.find("\"C=16\""), std::string::npos) << dat;
  EXPECT_TRUE(std::filesystem::exists(tmp / "sweep/rd_WOOL.png"));
  (void)f;
}

// With a ground truth beside the stacks the sweep adds its tables and a plot against it, with
// the noise floor; reports without one (older or real captures) keep the stack's alone.
TEST(Sweep, AGroundTruthAddsItsTablesAndPlotWithTheNoiseFloor) {
  json j = {{"material", {{"name", "fabric"}}}, {"method", "pca"}, {"method_family", "pca"}, {"method_parameter", 8},
            {"ratio", 800}, {"rmse", 0.03}, {"rmse_srgb8", 5.5}, {"rmse_holdout", 0.031}, {"blur_sigma", 0.8},
            {"rmse_ground_truth", 0.032}, {"rmse_ground_truth_holdout", 0.033}, {"rmse_reference_vs_ground_truth", 0.0186}};
  SweepEntry withTruth = sweepEntryFromReport(j, "r.json");
  EXPECT_EQ(withTruth.rmseGroundTruth, 0.032);
  EXPECT_EQ(withTruth.rmseGroundTruthHoldout, 0.033);
  EXPECT_EQ(withTruth.noiseFloor, 0.0186);
  for (const char* key : {"rmse_ground_truth", "rmse_ground_truth_holdout", "rmse_reference_vs_ground_truth"}) j.erase(key);
  EXPECT_TRUE(std::isnan(sweepEntryFromReport(j, "r.json").rmseGroundTruth));

  std::vector<SweepEntry> entries = sample();
  EXPECT_EQ(sweepTablesMarkdown(entries).find("ground truth"), std::string::npos);
  withTruth.material = "WOOL";
  entries.push_back(withTruth);
  const std::string md = sweepTablesMarkdown(entries);
  EXPECT_NE(md.find("### RMSE against the ground truth, all images"), std::string::npos) << md;
  EXPECT_NE(md.find("### Noise floor"), std::string::npos) << md;
  EXPECT_NE(md.find("0.0186"), std::string::npos) << md;
  test::TempDir tmp;
  SweepFiles files = writeSweepSummary(entries, tmp / "sweep");
  EXPECT_TRUE(std::filesystem::exists(tmp / "sweep/rd_WOOL_truth.png"));
  EXPECT_FALSE(std::filesystem::exists(tmp / "sweep/rd_fabric02_truth.png"));
  EXPECT_EQ(files.plots.size(), 3u);
}

TEST(Sweep, OddMaterialNamesMakePlainFileNames) {
  test::TempDir tmp;
  std::vector<SweepEntry> e = {entry("o'brien wool", "clustered-neural", 500, 5127, 0.03),
                               entry("o'brien wool", "clustered-neural", 1000, 4633, 0.029)};
  SweepFiles f = writeSweepSummary(e, tmp / "sweep");
  ASSERT_EQ(f.plots.size(), 1u);
  EXPECT_TRUE(std::filesystem::exists(f.plots[0]));
  EXPECT_EQ(std::filesystem::path(f.plots[0]).filename().string().find(' '), std::string::npos) << f.plots[0];
}

}  // namespace
}  // namespace nbtf
