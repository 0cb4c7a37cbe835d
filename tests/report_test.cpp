// The report on a small synthetic material: every section is there, the JSON parses with
// the documented keys, its numbers match the metrics, and every number printed in the
// Markdown tables is a JSON value. Set NBTF_REPORT_OUT=<dir> to keep the report (for looking
// at it: scripts/screenshot_report.sh <dir>/report.html out.png).
#include "eval/report.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "eval_fixtures.h"
#include "test_util.h"
#include "io/image_io.h"
#include "util/atomic_file.h"
#include "util/progress.h"

namespace nbtf {
namespace {

using json = ReportJson;

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

void collectNumbers(const json& j, std::vector<double>& out) {
  if (j.is_number()) out.push_back(j.get<double>());
  if (j.is_structured())
    for (const auto& v : j) collectNumbers(v, out);
}

struct Fixture {
  BtfStack ref = testing::syntheticStack(hemisphere81(), hemisphere81(), 16, 16, SampleType::Srgb8);
  EvalResult result;
  Fixture() {
    Progress::setQuiet(true);
    EvalInputs in;
    in.reference = &ref;
    in.alpha = 0.9f;
    in.reconstruct = testing::blurredReconstruction(ref, 0.8, 0.1);
    in.holdoutImages = {10, 500, 2000, 4000, 6000};
    in.method = "synthetic (reference blurred, sigma 0.8)";
    in.referenceName = "synthetic 16 x 16";
    in.compressedName = "synthetic.nbtf";
    in.details = {{"clusters (k)", "500"}};
    in.sizes.rawFloat32 = ref.rawFloat32Bytes();
    in.sizes.decoder = 97532, in.sizes.latents = 16000, in.sizes.ids = 512;
    in.sizes.total = 97532 + 16000 + 512, in.sizes.fileBytes = 120000;
    in.sizes.idsPaper = 1024, in.sizes.totalPaper = 97532 + 16000 + 1024;
    EvalOptions o;
    o.progress = false;
    o.blurSampleImages = 4;
    result = evaluate(in, o);
  }
};

const Fixture& fixture() {
  static Fixture f;
  return f;
}

TEST(Report, WritesEverySectionAndEmbedsTheFigures) {
  test::TempDir tmp;
  const char* keep = std::getenv("NBTF_REPORT_OUT");
  std::string dir = keep ? std::string(keep) : tmp / "report";
  ReportPaths p = writeReport(fixture().result, dir);
  std::string md = slurp(p.markdown), html = slurp(p.html);
  for (const char* section : {"## Summary", "## Size (the paper's Table 1)", "## Error by direction",
                              "## Image comparisons", "### #1 Fig. 7, top row", "### #2 Fig. 7, bottom row (grazing)",
                              "### #3 worst error", "## Effective blur", "## How these numbers are computed",
                              "By light elevation", "By view elevation", "held-out images"})
    EXPECT_NE(md.find(section), std::string::npos) << section;
  // 2 charts + the mean-brightness maps + 3 comparisons, as PNG files beside the report and embedded in the HTML.
  EXPECT_EQ(p.figures.size(), 6u);
  std::size_t embedded = 0;
  for (std::size_t at = 0; (at = html.find("src=\"data:image/png;base64,", at)) != std::string::npos; ++at) ++embedded;
  EXPECT_EQ(embedded, 6u);
  for (const auto& f : p.figures) {
    auto bytes = readFileBytes(f);
    ASSERT_GT(bytes.size(), 8u);
    EXPECT_EQ(bytes[1], 'P');  // PNG signature
    EXPECT_NE(md.find("](" + std::filesystem::path(f).filename().string() + ")"), std::string::npos);
  }
  EXPECT_EQ(html.find("<img src=\"rmse"), std::string::npos) << "no figure may be linked from the HTML";
  if (!keep) {
    std::size_t entries = 0;
    for (auto& e : std::filesystem::directory_iterator(dir)) entries += e.path().extension() == ".tmp";
    EXPECT_EQ(entries, 0u) << "no temporary files left behind";
  }
}

// `nbtf eval --render-compare DIR`: the folder `nbtf render --compare` writes becomes a section.
TEST(Report, IncludesARenderedComparison) {
  test::TempDir tmp;
  const std::string folder = tmp / "cmp";
  std::filesystem::create_directories(folder);
  std::vector<float> rgb(3 * 8 * 6, 0.25f);
  for (const char* name : {"reference.png", "compressed.png", "error.png"})
    writeImageSrgb8(folder + "/" + name, ImageFormat::Png, 8, 6, rgb.data());
  writeFileAtomic(folder + "/compare.json",
                  R"({"reference": "stack", "compressed": "f.nbtf", "scene": "sphere", "width": 8, "height": 6,
                      "sampling": "adaptive, 2 levels", "error_magnification": 8, "space": "linear RGB radiance",
                      "rmse": {"all": {"rmse": 0.013, "pixels": 48}, "dark10": {"rmse": 0.004, "pixels": 5},
                               "bright10": {"rmse": 0.074, "pixels": 5}}})");
  EvalResult r = fixture().result;
  r.render = loadRenderSection(folder);
  ReportPaths p = writeReport(r, tmp / "report");
  std::string md = slurp(p.markdown);
  EXPECT_NE(md.find("## Rendered comparison"), std::string::npos);
  EXPECT_NE(md.find("| Brightest 10% | 0.07400 |"), std::string::npos) << md;
  EXPECT_EQ(p.figures.size(), 9u);
  json j = json::parse(slurp(p.json));
  EXPECT_DOUBLE_EQ(j["render_comparison"]["rmse_dark10"].get<double>(), 0.004);
  EXPECT_TRUE(json::parse(slurp(writeReport(fixture().result, tmp / "plain").json))["render_comparison"].is_null());
  // A folder that is not a comparison is named.
  test::expectErrorContaining([&] { loadRenderSection(tmp / "report"); }, {"compare.json", "render --compare"});
  writeFileAtomic(folder + "/compare.json", "{\"scene\": 3}");
  test::expectErrorContaining([&] { loadRenderSection(folder); }, {"compare.json", "not a render comparison"});
}

TEST(Report, JsonHasTheDocumentedKeysAndTheMetrics) {
  const EvalResult& r = fixture().result;
  json j = json::parse(reportJson(r).dump());
  for (const char* key : {"rmse", "rmse_srgb8", "psnr", "psnr_srgb8", "rmse_training", "rmse_holdout", "ratio", "bytes",
                          "blur_sigma", "blur", "by_light_elevation", "by_view_elevation", "worst_pair", "comparisons",
                          "rmse_by_image", "material", "spaces", "holdout_images", "lights", "views"})
    EXPECT_TRUE(j.contains(key)) << key;
  for (const char* key : {"decoder", "latents", "ids", "total", "raw_float32", "file"})
    EXPECT_TRUE(j["bytes"].contains(key)) << key;
  EXPECT_DOUBLE_EQ(j["rmse"].get<double>(), r.all.rmse);
  EXPECT_DOUBLE_EQ(j["rmse_srgb8"].get<double>(), r.all.rmseSrgb8);
  EXPECT_DOUBLE_EQ(j["rmse_holdout"].get<double>(), r.holdout.rmse);
  EXPECT_DOUBLE_EQ(j["psnr"].get<double>(), 20 * std::log10(1 / r.all.rmse));
  EXPECT_EQ(j["bytes"]["raw_float32"].get<std::uint64_t>(), 6561ull * 256 * 3 * 4);
  EXPECT_DOUBLE_EQ(j["ratio"].get<double>(), 6561.0 * 256 * 3 * 4 / (97532 + 16000 + 512));
  EXPECT_DOUBLE_EQ(j["ratio_paper"].get<double>(), 6561.0 * 256 * 3 * 4 / (97532 + 16000 + 1024));
  EXPECT_EQ(j["rmse_by_image"].size(), 81u);
  EXPECT_EQ(j["rmse_by_image"][80].size(), 81u);
  EXPECT_DOUBLE_EQ(j["rmse_by_image"][2][5].get<double>(), r.table.image(2 * 81 + 5).rmse);
  EXPECT_EQ(j["comparisons"].size(), 3u);
  EXPECT_EQ(j["comparisons"][0]["view"]["theta"].get<double>(), 15);
  EXPECT_EQ(j["comparisons"][0]["light"]["theta"].get<double>(), 30);
  EXPECT_TRUE(j["comparisons"][1]["exact"].get<bool>());
  EXPECT_EQ(j["worst_pair"]["image"].get<int>(), r.worstImage);
  EXPECT_NEAR(j["blur_sigma"].get<double>(), 0.8, 0.08);
  EXPECT_EQ(j["by_view_elevation"].size(), 6u);
  EXPECT_EQ(j["by_view_elevation"][3]["directions"].get<int>(), 18);
}

TEST(Report, EveryNumberInTheMarkdownTablesIsAJsonValue) {
  json j = reportJson(fixture().result);
  std::vector<double> numbers;
  collectNumbers(j, numbers);
  // The settings table prints `details`, which the JSON holds as strings.
  const std::regex digits(R"(\d+(\.\d+)?)");
  for (const auto& [key, value] : j["details"].items()) {
    std::string text = key + " " + value.get<std::string>();
    for (std::sregex_iterator it(text.begin(), text.end(), digits), end; it != end; ++it)
      numbers.push_back(std::stod(it->str()));
  }
  std::string md = renderMarkdown(reportDoc(j));
  std::istringstream lines(md);
  std::string line;
  // Unit words that contain digits, then thousands separators of byte counts.
  const std::regex units(R"(eq\. ?\(?10\)?|8-bit|\d-byte|0-255|float32|peak \d+|#\d+|log10)");
  const std::regex number(R"((\d+)(?:\.(\d+))?(?:e([-+]\d+))?)");
  int checked = 0;
  bool header = true;
  while (std::getline(lines, line)) {
    if (line.rfind("|", 0) != 0) {
      header = true;
      continue;
    }
    if (header || line.rfind("|---", 0) == 0) {  // a table's header row and its separator
      header = line.rfind("|---", 0) != 0;
      continue;
    }
    if (line.find("iB |") != std::string::npos) continue;  // KiB / MiB: unit conversions of bytes
    std::string text = std::regex_replace(line, units, " ");
    std::string noCommas;
    for (std::size_t i = 0; i < text.size(); ++i)
      if (!(text[i] == ',' && i > 0 && i + 1 < text.size() && std::isdigit(text[i - 1]) && std::isdigit(text[i + 1])))
        noCommas += text[i];
    for (std::sregex_iterator it(noCommas.begin(), noCommas.end(), number), end; it != end; ++it) {
      const auto& m = *it;
      double value = std::stod(m.str(0));
      int decimals = m[2].matched ? static_cast<int>(m[2].length()) : 0;
      int exponent = m[3].matched ? std::stoi(m[3].str()) : 0;
      double tolerance = 0.5 * std::pow(10.0, exponent - decimals) * 1.0001;
      bool found = false;
      for (double v : numbers) found = found || std::abs(v - value) <= tolerance;
      EXPECT_TRUE(found) << "'" << m.str(0) << "' in line: " << line;
      ++checked;
    }
  }
  EXPECT_GT(checked, 60);
}

TEST(Report, InfinitePsnrIsNullInJsonAndSaidInWords) {
  BtfStack ref = testing::syntheticStack({{0, 0}, {30, 0}}, {{15, 60}, {75, 345}}, 6, 6);
  EvalInputs in;
  in.reference = &ref;
  in.reconstruct = [&](int image, float* out) { ref.imageLinear(image, out); };
  in.method = "identity";
  EvalOptions o;
  o.progress = false;
  json j = reportJson(evaluate(in, o));
  EXPECT_TRUE(j["psnr"].is_null());
  EXPECT_TRUE(j["rmse_holdout"].is_null());
  EXPECT_TRUE(j["bytes"].is_null());
  EXPECT_TRUE(j["ratio"].is_null());
  std::string md = renderMarkdown(reportDoc(j));
  EXPECT_NE(md.find("infinite (identical)"), std::string::npos);
  EXPECT_NE(md.find("No held-out images"), std::string::npos);
  EXPECT_NE(md.find("No size table"), std::string::npos);
  EXPECT_NE(md.find("not measured in this data set"), std::string::npos);  // light (30, 60) is absent
}

TEST(Report, UnwritableFolderIsAClearError) {
  test::TempDir tmp;
  std::string file = tmp / "a_file";
  writeFileAtomic(file, std::string("x"));
  test::expectErrorContaining([&] { writeReport(fixture().result, file + "/report"); }, {"a_file", "report folder"});
}

// Clustered materials get a cluster map; adaptive ones (generations given) say per generation.
TEST(Report, ClusterMapShowsSplitGenerations) {
  test::TempDir tmp;
  const Fixture& f = fixture();
  EvalInputs in;
  in.reference = &f.ref;
  in.alpha = 0.9f;
  in.reconstruct = testing::blurredReconstruction(f.ref, 0.8, 0.1);
  in.method = "synthetic";
  const int texels = f.ref.numTexels();
  in.clusters = 3;
  for (int t = 0; t < texels; ++t) in.clusterIds.push_back(t % 16 < 8 ? 0 : (t / 16 < 8 ? 1 : 2));
  in.clusterGenerations = {0, 1, 1};
  EvalOptions o;
  o.progress = false;
  o.blurSampleImages = 1;
  ReportPaths p = writeReport(evaluate(in, o), tmp / "report");
  std::string md = slurp(p.markdown);
  EXPECT_NE(md.find("## Cluster map"), std::string::npos);
  EXPECT_NE(md.find("Clusters per generation: 0: 1, 1: 2."), std::string::npos) << md;
  EXPECT_NE(md.find("](cluster_map.png)"), std::string::npos);
  json j = json::parse(slurp(p.json));
  EXPECT_EQ(j["figures"]["cluster_map"], "cluster_map.png");
  EXPECT_EQ(j["clusters_per_generation"], json::array({1, 2}));
  EXPECT_TRUE(json::parse(slurp(writeReport(f.result, tmp / "plain").json))["clusters_per_generation"].is_null());
}

}  // namespace
}  // namespace nbtf
