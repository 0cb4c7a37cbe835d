#include "eval/sweep.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include "eval/figures.h"
#include "io/image_io.h"
#include "util/atomic_file.h"
#include "util/error.h"

namespace nbtf {

using nlohmann::json;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

const json& requireKey(const json& j, const char* key, const std::string& path) {
  if (!j.is_object() || !j.contains(key)) throw fileError(path, std::string("missing key '") + key + "'");
  return j[key];
}
double number(const json& j, const char* key, const std::string& path, bool nullable = false) {
  const json& v = requireKey(j, key, path);
  if (v.is_null() && nullable) return kNaN;
  if (!v.is_number()) throw fileError(path, std::string("key '") + key + "' is not a number");
  return v.get<double>();
}
std::string text(const json& j, const char* key, const std::string& path) {
  const json& v = requireKey(j, key, path);
  if (!v.is_string()) throw fileError(path, std::string("key '") + key + "' is not a string");
  return v.get<std::string>();
}

std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

// File-name-safe version of a label.
std::string slug(const std::string& s) {
  std::string out;
  for (char c : s) out += std::isalnum(static_cast<unsigned char>(c)) || c == '-' ? c : '_';
  return out;
}

// Family order in tables and plots: the baseline first, then the paper's methods.
int familyRank(const std::string& f) {
  if (f == "pca") return 0;
  if (f == "per-texel-neural") return 1;
  if (f == "clustered-neural") return 2;
  return 3;
}
bool methodBefore(const SweepEntry& a, const SweepEntry& b) {
  if (familyRank(a.family) != familyRank(b.family)) return familyRank(a.family) < familyRank(b.family);
  if (a.family != b.family) return a.family < b.family;
  double pa = std::isnan(a.parameter) ? -1 : a.parameter, pb = std::isnan(b.parameter) ? -1 : b.parameter;
  if (pa != pb) return pa < pb;
  return a.method < b.method;
}

std::string familyTitle(const std::string& f) {
  if (f == "pca") return "PCA (baseline)";
  if (f == "per-texel-neural") return "per-texel neural BTF";
  if (f == "clustered-neural") return "clustered neural BTF";
  return f;
}

}  // namespace

SweepEntry sweepEntryFromReport(const json& j, const std::string& path) {
  SweepEntry e;
  e.material = text(requireKey(j, "material", path), "name", path);
  e.method = text(j, "method", path);
  e.family = j.contains("method_family") && j["method_family"].is_string() ? j["method_family"].get<std::string>()
                                                                            : e.method;
  e.parameter = j.contains("method_parameter") ? number(j, "method_parameter", path, true) : kNaN;
  e.ratio = number(j, "ratio", path, true);
  if (std::isnan(e.ratio)) throw fileError(path, "has no compression ratio (not a compressed material's report)");
  e.rmse = number(j, "rmse", path);
  e.rmseSrgb8 = number(j, "rmse_srgb8", path);
  e.rmseHoldout = number(j, "rmse_holdout", path, true);
  e.blurSigma = number(j, "blur_sigma", path);
  // Reports written before the ground-truth keys existed have none of them.
  auto optional = [&](const char* key) { return j.contains(key) ? number(j, key, path, true) : kNaN; };
  e.rmseGroundTruth = optional("rmse_ground_truth");
  e.rmseGroundTruthHoldout = optional("rmse_ground_truth_holdout");
  e.noiseFloor = optional("rmse_reference_vs_ground_truth");
  e.report = path;
  return e;
}

SweepEntry readSweepEntry(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw fileError(path, "is a folder, expected a report.json file");
  std::ifstream in(path);
  if (!in) throw fileError(path, "cannot be read");
  json j;
  try {
    j = json::parse(in);
  } catch (const std::exception& ex) {
    throw fileError(path, std::string("is not valid JSON: ") + ex.what());
  }
  return sweepEntryFromReport(j, path);
}

std::string sweepTablesMarkdown(const std::vector<SweepEntry>& entriesIn) {
  std::vector<SweepEntry> entries = entriesIn;
  std::stable_sort(entries.begin(), entries.end(), methodBefore);
  std::vector<std::string> methods, materials;
  for (const auto& e : entries) {
    if (std::find(methods.begin(), methods.end(), e.method) == methods.end()) methods.push_back(e.method);
    if (std::find(materials.begin(), materials.end(), e.material) == materials.end()) materials.push_back(e.material);
  }
  std::sort(materials.begin(), materials.end());
  std::map<std::pair<std::string, std::string>, const SweepEntry*> cell;
  for (const auto& e : entries) {
    auto key = std::make_pair(e.material, e.method);
    if (cell.count(key)) throw Error("sweep: two reports for material '" + e.material + "' and method '" + e.method +
                                     "': " + cell[key]->report + " and " + e.report);
    cell[key] = &e;
  }
  bool anyHoldout = std::any_of(entries.begin(), entries.end(), [](const SweepEntry& e) { return !std::isnan(e.rmseHoldout); });

  std::ostringstream md;
  auto table = [&](const std::string& title, const std::string& unitNote, auto value) {
    md << "### " << title << "\n\n" << unitNote << "\n\n| material |";
    for (const auto& m : methods) md << ' ' << m << " |";
    md << "\n|---|";
    for (std::size_t i = 0; i < methods.size(); ++i) md << "---:|";
    md << '\n';
    for (const auto& mat : materials) {
      md << "| " << mat << " |";
      for (const auto& m : methods) {
        auto it = cell.find({mat, m});
        md << ' ' << (it == cell.end() ? std::string("-") : value(*it->second)) << " |";
      }
      md << '\n';
    }
    md << '\n';
  };
  md << "## Sweep: RMSE by material and method (the paper's Table 2 layout)\n\n";
  table("RMSE, all images", "Linear RGB / alpha, eq. (10) of the paper (4 decimals, as in its Table 2).",
        [](const SweepEntry& e) { return fmt("%.4f", e.rmse); });
  if (anyHoldout)
    table("RMSE, held-out images (interpolation)",
          "Linear RGB / alpha, on the images kept out of training (or out of the PCA fit).",
          [](const SweepEntry& e) { return std::isnan(e.rmseHoldout) ? std::string("-") : fmt("%.4f", e.rmseHoldout); });
  auto fourDecimals = [](double v) { return std::isnan(v) ? std::string("-") : fmt("%.4f", v); };
  if (std::any_of(entries.begin(), entries.end(), [](const SweepEntry& e) { return !std::isnan(e.rmseGroundTruth); })) {
    table("RMSE against the ground truth, all images",
          "Linear RGB / alpha, against the float ground truth beside the stack (not its 8-bit images).",
          [&](const SweepEntry& e) { return fourDecimals(e.rmseGroundTruth); });
    if (anyHoldout)
      table("RMSE against the ground truth, held-out images", "Linear RGB / alpha, as above, on the held-out images.",
            [&](const SweepEntry& e) { return fourDecimals(e.rmseGroundTruthHoldout); });
    table("Noise floor", "The stack itself against the ground truth, all images (linear RGB / alpha): what its "
          "encoding lost; the same in every column of a material.",
          [&](const SweepEntry& e) { return fourDecimals(e.noiseFloor); });
  }
  table("RMSE in 8-bit sRGB", "sRGB code values 0-255.", [](const SweepEntry& e) { return fmt("%.2f", e.rmseSrgb8); });
  table("Compression ratio",
        "Raw float32 size / total compressed size (neural: decoder + latents + id list; PCA: mean + basis + "
        "coefficients), 1 : x.",
        [](const SweepEntry& e) { return "1 : " + fmt("%.0f", e.ratio); });
  table("Effective blur sigma", "Texels (median over the estimated images; below ~0.3 = no measurable blur).",
        [](const SweepEntry& e) { return fmt("%.2f", e.blurSigma); });
  return md.str();
}

namespace {
// "k=500" on a clustered point, "C=16" on a PCA point; empty without a parameter.
std::string pointLabel(const SweepEntry& e) {
  if (std::isnan(e.parameter)) return "";
  return (e.family == "clustered-neural" ? "k=" : e.family == "pca" ? "C=" : "") + fmt("%g", e.parameter);
}

Color8 familyColor(const std::string& family, std::size_t i) {
  // The three named families keep their colours; the others (model kinds: planes, cluster
  // planes, modulation...) take distinct ones by their place in the list.
  static const Color8 colors[] = {{0x55, 0x55, 0x55}, {0xe0, 0x7b, 0x39}, {0x2a, 0x6f, 0x97},
                                  {0x6a, 0x99, 0x4e}, {0x9d, 0x4e, 0xdd}, {0xd6, 0x27, 0x28},
                                  {0x17, 0xbe, 0xcf}, {0x8c, 0x56, 0x4b}, {0xe3, 0x77, 0xc2}, {0xbc, 0xbd, 0x22}};
  constexpr std::size_t kOthers = sizeof colors / sizeof colors[0] - 3;
  int rank = familyRank(family);
  return colors[rank < 3 ? static_cast<std::size_t>(rank) : 3 + i % kOthers];
}

// What a rate-distortion plot draws on its y axis.
struct RdMeasure {
  double SweepEntry::*rmse;
  const char* title;  // before ": <material>"
  const char* axis;
};
const RdMeasure kAgainstStack{&SweepEntry::rmse, "Rate-distortion", "RMSE (linear RGB / alpha, eq. 10)"};
const RdMeasure kAgainstTruth{&SweepEntry::rmseGroundTruth, "Against the truth", "RMSE vs truth (linear RGB / alpha)"};

// The noise floor as a flat line over the plotted ratios (empty without a ground truth).
ChartSeries noiseFloorLine(const std::vector<SweepEntry>& entries) {
  ChartSeries line;
  line.name = "noise floor (the stack vs the truth)";
  line.color = {0x99, 0x99, 0x99};
  double floor = kNaN, lo = HUGE_VAL, hi = 0;
  for (const auto& e : entries) {
    if (!std::isnan(e.noiseFloor)) floor = e.noiseFloor;
    lo = std::min(lo, std::max(e.ratio, 1e-12)), hi = std::max(hi, std::max(e.ratio, 1e-12));
  }
  if (std::isnan(floor)) return line;
  line.x = {lo, hi}, line.y = {floor, floor}, line.labels = {"", ""};
  return line;
}

// The rate-distortion plot drawn by nbtf: x = log10 of the ratio (the line chart's axes are linear).
Image8 rateDistortionChart(const std::string& material, const std::vector<SweepEntry>& entries,
                           const std::vector<std::string>& families, const RdMeasure& measure = kAgainstStack) {
  std::vector<ChartSeries> series;
  for (std::size_t i = 0; i < families.size(); ++i) {
    ChartSeries s;
    s.name = familyTitle(families[i]);
    s.color = familyColor(families[i], i);
    std::vector<const SweepEntry*> pts;
    for (const auto& e : entries)
      if (e.family == families[i]) pts.push_back(&e);
    std::sort(pts.begin(), pts.end(), [](const SweepEntry* a, const SweepEntry* b) { return a->ratio < b->ratio; });
    for (const auto* e : pts) {
      if (std::isnan((*e).*measure.rmse)) continue;
      s.x.push_back(std::max(e->ratio, 1e-12)), s.y.push_back((*e).*measure.rmse);
      s.labels.push_back(pointLabel(*e));
    }
    if (!s.x.empty()) series.push_back(std::move(s));
  }
  if (measure.rmse == kAgainstTruth.rmse) {
    ChartSeries floor = noiseFloorLine(entries);
    if (!floor.x.empty()) series.push_back(std::move(floor));
  }
  ChartAxes axes;
  axes.logX = true;
  axes.xTickPrefix = "1:";
  return renderLineChart(series, std::string(measure.title) + ": " + material,
                         "compression ratio (raw float32 / total), log scale", measure.axis, axes);
}
}  // namespace

SweepFiles writeSweepSummary(const std::vector<SweepEntry>& entries, const std::string& dir) {
  namespace fs = std::filesystem;
  if (entries.empty()) throw Error("sweep: no reports to summarize");
  // The tables check the entries (duplicates): before the folder is made, so a refused
  // summary leaves nothing behind.
  const std::string tables = "# BTF compression sweep\n\n" + sweepTablesMarkdown(entries);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) throw fileError(dir, "cannot create the sweep folder: " + ec.message());
  auto path = [&](const std::string& name) { return (fs::path(dir) / name).string(); };
  SweepFiles out;
  out.table = path("sweep.md");
  writeFileAtomic(out.table, tables);

  std::set<std::string> materials;
  for (const auto& e : entries) materials.insert(e.material);
  for (const auto& mat : materials) {
    std::vector<SweepEntry> mine;
    for (const auto& e : entries)
      if (e.material == mat) mine.push_back(e);
    std::stable_sort(mine.begin(), mine.end(), methodBefore);
    std::vector<std::string> families;
    for (const auto& e : mine)
      if (std::find(families.begin(), families.end(), e.family) == families.end()) families.push_back(e.family);
    for (const auto& fam : families) {
      // One point per setting, sorted by ratio so the curve runs left to right.
      std::vector<const SweepEntry*> pts;
      for (const auto& e : mine)
        if (e.family == fam) pts.push_back(&e);
      std::sort(pts.begin(), pts.end(), [](const SweepEntry* a, const SweepEntry* b) { return a->ratio < b->ratio; });
      std::ostringstream dat;
      dat << "# " << mat << ", " << fam
          << ": ratio (raw/total)  rmse (linear/alpha)  rmse_holdout (NaN = none)  parameter  label\n";
      for (const auto* e : pts) {
        std::string label = pointLabel(*e);
        dat << fmt("%.6g", e->ratio) << ' ' << fmt("%.8g", e->rmse) << ' '
            << (std::isnan(e->rmseHoldout) ? std::string("NaN") : fmt("%.8g", e->rmseHoldout)) << ' '
            << (std::isnan(e->parameter) ? std::string("NaN") : fmt("%g", e->parameter)) << " \""
            << label << "\"\n";
      }
      std::string name = "rd_" + slug(mat) + "_" + slug(fam) + ".dat";
      writeFileAtomic(path(name), dat.str());
      out.dataFiles.push_back(path(name));
    }
    std::string png = "rd_" + slug(mat) + ".png";
    writeImage8(path(png), ImageFormat::Png, rateDistortionChart(mat, mine, families));
    out.plots.push_back(path(png));
    if (std::any_of(mine.begin(), mine.end(), [](const SweepEntry& e) { return !std::isnan(e.rmseGroundTruth); })) {
      std::string truthPng = "rd_" + slug(mat) + "_truth.png";
      writeImage8(path(truthPng), ImageFormat::Png, rateDistortionChart(mat, mine, families, kAgainstTruth));
      out.plots.push_back(path(truthPng));
    }
  }
  return out;
}

}  // namespace nbtf
