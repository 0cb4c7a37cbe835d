// Sweep summaries: many evaluation reports (report.json) of one or more materials, each
// compressed with several methods and settings, turned into the paper's Table 2 layout
// (rows: materials, columns: methods) as Markdown, and a rate-distortion plot per material
// (RMSE vs compression ratio, log-scale x, one curve per method family) as a PNG drawn by
// nbtf's own chart code (eval/figures.h), with the points as data files for other tools.
#pragma once
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace nbtf {

struct SweepEntry {
  std::string material;  // report material.name
  std::string family;    // method_family: one curve each
  std::string method;    // column label, e.g. "clustered neural, k = 500"
  double parameter = 0;  // method_parameter (k, components); NaN = none
  double ratio = 0;      // raw float32 / total
  double rmse = 0, rmseSrgb8 = 0;  // linear RGB / alpha; sRGB 8-bit
  double rmseHoldout = 0;          // NaN = no held-out images
  double blurSigma = 0;            // texels
  // Against the float ground truth beside the stack (linear RGB / alpha), all and held-out
  // images, and the stack's own distance from it (the noise floor); NaN = no ground truth.
  double rmseGroundTruth = std::numeric_limits<double>::quiet_NaN();
  double rmseGroundTruthHoldout = std::numeric_limits<double>::quiet_NaN();
  double noiseFloor = std::numeric_limits<double>::quiet_NaN();
  std::string report;              // the report.json it came from
};

// Reads the keys a sweep needs; throws nbtf::Error naming `path` and the missing or mistyped key.
SweepEntry sweepEntryFromReport(const nlohmann::json& report, const std::string& path);
SweepEntry readSweepEntry(const std::string& reportJsonPath);

// Table 2 style: one row per material, one column per method (ordered by family, then
// parameter), cells RMSE (linear RGB / alpha), then the same for sRGB 8-bit, held-out RMSE
// (when any report has one), compression ratios and effective blur.
std::string sweepTablesMarkdown(const std::vector<SweepEntry>& entries);

struct SweepFiles {
  std::string table;                   // sweep.md
  std::vector<std::string> dataFiles;  // rd_<material>_<family>.dat
  std::vector<std::string> plots;      // rd_<material>.png (log ratio axis, drawn by nbtf)
};
// Writes sweep.md, the data files (for other plotting tools) and one rate-distortion PNG per
// material (log ratio axis, points labelled k= / C=; drawn here, no external program) into
// `dir` (atomic writes; the folder is created if missing).
SweepFiles writeSweepSummary(const std::vector<SweepEntry>& entries, const std::string& dir);

}  // namespace nbtf
