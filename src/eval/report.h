// The evaluation report: report.json (every number, stable keys), report.md and a
// self-contained report.html (figures embedded), plus the figures as PNG files beside them.
//
// The JSON is built first and is the single source of the text: the Markdown and HTML are
// rendered from it, so every number they print is a JSON value (shown rounded). Keys and
// their spaces are documented in docs/evaluation.md.
#pragma once
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "eval/evaluate.h"
#include "eval/report_doc.h"

namespace nbtf {

// Figure file names inside the report folder.
constexpr const char* kHeatMapFile = "rmse_heatmap.png";
constexpr const char* kElevationFile = "rmse_by_elevation.png";
constexpr const char* kMeanMapFile = "mean_brightness.png";
constexpr const char* kClusterMapFile = "cluster_map.png";  // clustered materials only
constexpr const char* kRenderFiles[3] = {"render_reference.png", "render_compressed.png", "render_error.png"};
std::string comparisonFile(std::size_t index);  // "comparison_1.png", ...

// Keys keep the order they are written in (a person reads report.json too).
using ReportJson = nlohmann::ordered_json;
ReportJson reportJson(const EvalResult& result);
// The report document, from the JSON alone.
Doc reportDoc(const ReportJson& report);

struct ReportPaths {
  std::string markdown, html, json;
  std::vector<std::string> figures;
};
// Writes everything into `dir` (created if missing). Each file is written atomically.
ReportPaths writeReport(const EvalResult& result, const std::string& dir);

}  // namespace nbtf
