#include "eval/report.h"

#include <cmath>
#include <cstdio>
#include <filesystem>

#include "eval/figures.h"
#include "util/atomic_file.h"
#include "util/error.h"

namespace nbtf {

using json = ReportJson;

std::string comparisonFile(std::size_t index) { return "comparison_" + std::to_string(index + 1) + ".png"; }

// ---- JSON

namespace {

// +infinity (identical images) has no JSON form: null, and the text says "identical".
json finiteOrNull(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

// The reference's folder name ("data/WOOL/" -> "WOOL"), the material's name in sweep tables.
std::string materialName(const std::string& reference) {
  std::filesystem::path p(reference);
  while (!p.empty() && p.filename().empty()) p = p.parent_path();
  std::string name = p.filename().string();
  return name.empty() ? reference : name;
}

json directionJson(const Direction& d) { return {{"theta", d.thetaDeg}, {"phi", d.phiDeg}}; }

json elevationJson(const std::vector<ElevationError>& rows) {
  json out = json::array();
  for (const auto& r : rows)
    out.push_back({{"theta", r.thetaDeg},
                   {"directions", r.directions},
                   {"images", r.images},
                   {"rmse", r.error.rmse},
                   {"rmse_srgb8", r.error.rmseSrgb8}});
  return out;
}

json blurJson(const BlurEstimate& b) {
  return {{"sigma", b.sigma},          {"rmse_before", b.rmseBefore}, {"rmse_after", b.rmseAfter},
          {"iterations", b.iterations}, {"converged", b.converged},    {"start_sigma", b.initialSigma},
          {"at_upper_bound", b.atUpperBound}, {"upper_bound", b.upperBound}};
}

}  // namespace

namespace {

// What was compared: the method, the reference, the material and the spaces of every number.
void addContext(const EvalResult& r, json& j) {
  j["format"] = "nbtf-eval-report";
  j["version"] = 1;
  j["method"] = r.method;
  j["method_family"] = r.methodFamily;
  j["method_parameter"] = finiteOrNull(r.methodParameter);
  j["reference"] = r.referenceName;
  j["compressed"] = r.compressedName.empty() ? json(nullptr) : json(r.compressedName);
  json details = json::object();
  for (const auto& [k, v] : r.details) details[k] = v;
  j["details"] = details;
  j["material"] = {{"name", materialName(r.referenceName)},
                   {"width", r.width},
                   {"height", r.height},
                   {"texels", r.width * r.height},
                   {"lights", r.lights.size()},
                   {"views", r.views.size()},
                   {"images", r.lights.size() * r.views.size()},
                   {"alpha", r.alpha},
                   {"alpha_source", r.alphaFromReference ? "reference maximum" : "compressed file"}};
  j["spaces"] = {
      {"rmse", "linear RGB divided by alpha (eq. 10 of the paper)"},
      {"rmse_srgb8", "8-bit sRGB code values 0..255 (both sides sRGB-encoded, clamped, rounded)"},
      {"psnr", "dB, peak 1 in linear RGB divided by alpha"},
      {"psnr_srgb8", "dB, peak 255 in 8-bit sRGB code values"},
      {"blur_sigma", "texels (Gaussian standard deviation)"},
      {"mean_brightness_rmse", "linear RGB divided by alpha, between per-texel means over all images"},
      {"floor_rmse", "linear RGB divided by alpha, all images: the cluster means (with the per-texel factors: "
                     "floor_rmse_modulated) against the reference"},
      {"bytes", "bytes"},
      {"ratio", "raw float32 bytes / total bytes"},
  };
}

// The headline metrics: RMSE and PSNR, on training and held-out images, against the reference and the ground truth.
void addHeadline(const EvalResult& r, json& j) {
  j["values"] = r.all.count;
  j["rmse"] = r.all.rmse;
  j["rmse_srgb8"] = r.all.rmseSrgb8;
  j["psnr"] = finiteOrNull(r.all.psnr);
  j["psnr_srgb8"] = finiteOrNull(r.all.psnrSrgb8);
  j["holdout_images"] = r.holdoutImages;
  j["holdout_count"] = r.holdoutImages.size();
  j["rmse_training"] = r.training.rmse;
  j["rmse_srgb8_training"] = r.training.rmseSrgb8;
  j["rmse_holdout"] = r.hasHoldout() ? json(r.holdout.rmse) : json(nullptr);
  j["rmse_srgb8_holdout"] = r.hasHoldout() ? json(r.holdout.rmseSrgb8) : json(nullptr);
  // Against the float ground truth, when the reference has one (null otherwise).
  auto truth = [&](const ErrorSummary& e, bool present) { return present ? json(e.rmse) : json(nullptr); };
  j["ground_truth"] = r.hasGroundTruth ? json(r.groundTruthName) : json(nullptr);
  j["rmse_ground_truth"] = truth(r.groundTruthAll, r.hasGroundTruth);
  j["rmse_ground_truth_training"] = truth(r.groundTruthTraining, r.hasGroundTruth);
  j["rmse_ground_truth_holdout"] = truth(r.groundTruthHoldout, r.hasGroundTruth && r.hasHoldout());
  j["rmse_reference_vs_ground_truth"] = truth(r.referenceVsGroundTruth, r.hasGroundTruth);
  j["rmse_reference_vs_ground_truth_holdout"] =
      truth(r.referenceVsGroundTruthHoldout, r.hasGroundTruth && r.hasHoldout());
  j["reference_encoding"] = r.referenceEncoding;
  j["noise_floor_cause"] = r.hasGroundTruth ? json(r.noiseFloorCause) : json(nullptr);
  j["psnr_holdout"] = r.hasHoldout() ? finiteOrNull(r.holdout.psnr) : json(nullptr);
  j["mean_brightness_rmse"] = r.meanMapRmse;
  j["mean_brightness_display_gain"] = r.meanMapGain;
  j["mean_brightness_error_magnification"] = r.meanMapMagnification;
  j["floor_rmse"] = r.floorRmse >= 0 ? json(r.floorRmse) : json(nullptr);
  j["floor_rmse_modulated"] = r.floorRmseModulated >= 0 ? json(r.floorRmseModulated) : json(nullptr);
}

// The Table-1 sizes and the ratio (null when the file's size is not known).
void addSizes(const EvalResult& r, json& j) {
  if (r.sizes.known()) {
    if (r.sizes.gltf)
      j["bytes"] = {{"raw_float32", r.sizes.rawFloat32}, {"gltf_textures", r.sizes.textures}, {"total", r.sizes.total},
                    {"file", r.sizes.fileBytes ? json(r.sizes.fileBytes) : json(nullptr)}};
    else if (r.sizes.pca)
      j["bytes"] = {{"raw_float32", r.sizes.rawFloat32},
                    {"pca_mean", r.sizes.pcaMean},
                    {"pca_basis", r.sizes.pcaBasis},
                    {"pca_coefficients", r.sizes.pcaCoefficients},
                    {"pca_components", r.sizes.pcaComponents},
                    {"total", r.sizes.total},
                    {"file", r.sizes.fileBytes ? json(r.sizes.fileBytes) : json(nullptr)}};
    else
      j["bytes"] = {{"raw_float32", r.sizes.rawFloat32}, {"decoder", r.sizes.decoder}, {"latents", r.sizes.latents},
                    {"ids", r.sizes.ids},                 {"per_texel", r.sizes.perTexel}, {"total", r.sizes.total},
                    {"file", r.sizes.fileBytes ? json(r.sizes.fileBytes) : json(nullptr)}};
    if (r.sizes.planes) j["bytes"]["planes"] = r.sizes.planes;
    if (r.sizes.clusterPlanes) j["bytes"]["cluster_planes"] = r.sizes.clusterPlanes;
    j["ratio"] = r.sizes.ratio();
    if (r.sizes.totalPaper && r.sizes.totalPaper != r.sizes.total) {
      j["bytes"]["ids_paper"] = r.sizes.idsPaper;
      j["bytes"]["total_paper"] = r.sizes.totalPaper;
      j["ratio_paper"] = static_cast<double>(r.sizes.rawFloat32) / static_cast<double>(r.sizes.totalPaper);
    }
  } else {
    j["bytes"] = nullptr;
    j["ratio"] = nullptr;
  }
}

// The error by light and view elevation and per image, the worst pair, the directions.
void addErrorByDirection(const EvalResult& r, json& j) {
  const int nv = static_cast<int>(r.views.size());
  j["by_light_elevation"] = elevationJson(r.byLightElevation);
  j["by_view_elevation"] = elevationJson(r.byViewElevation);
  ErrorSummary worst = r.table.image(r.worstImage);
  j["worst_pair"] = {{"image", r.worstImage},
                     {"light_index", r.worstImage / nv},
                     {"view_index", r.worstImage % nv},
                     {"light", directionJson(r.lights[r.worstImage / nv])},
                     {"view", directionJson(r.views[r.worstImage % nv])},
                     {"rmse", worst.rmse},
                     {"rmse_srgb8", worst.rmseSrgb8}};
  json map = json::array();
  auto rmse = r.table.rmseMap();
  for (std::size_t l = 0; l < r.lights.size(); ++l)
    map.push_back(std::vector<double>(rmse.begin() + l * nv, rmse.begin() + (l + 1) * nv));
  j["rmse_by_image"] = map;
  j["lights"] = json::array();
  for (const auto& d : r.lights) j["lights"].push_back(directionJson(d));
  j["views"] = json::array();
  for (const auto& d : r.views) j["views"].push_back(directionJson(d));
}

// The comparison images: requested and chosen pairs, their errors and figures.
void addComparisons(const EvalResult& r, json& j) {
  json comps = json::array();
  for (std::size_t i = 0; i < r.comparisons.size(); ++i) {
    const auto& c = r.comparisons[i];
    comps.push_back({{"name", c.name},
                     {"note", c.note},
                     {"requested_light", directionJson(c.requested.light)},
                     {"requested_view", directionJson(c.requested.view)},
                     {"exact", c.exact},
                     {"image", c.image},
                     {"light_index", c.light},
                     {"view_index", c.view},
                     {"light", directionJson(r.lights[c.light])},
                     {"view", directionJson(r.views[c.view])},
                     {"rmse", c.error.rmse},
                     {"rmse_srgb8", c.error.rmseSrgb8},
                     {"psnr", finiteOrNull(c.error.psnr)},
                     {"error_magnification", c.magnification},
                     {"blur", blurJson(c.blur)},
                     {"figure", comparisonFile(i)}});
  }
  j["comparisons"] = comps;
}

// The effective blur: per estimated image and the median.
void addBlur(const EvalResult& r, json& j) {
  json samples = json::array();
  for (const auto& s : r.blurSamples) {
    json b = blurJson(s.estimate);
    b["image"] = s.image, b["light_index"] = s.light, b["view_index"] = s.view;
    b["light"] = directionJson(r.lights[s.light]), b["view"] = directionJson(r.views[s.view]);
    samples.push_back(b);
  }
  j["blur_sigma"] = r.blurSigmaMedian;
  j["blur"] = {{"images", samples},
               {"image_count", samples.size()},
               {"statistic", "median over the estimated images"},
               {"border", blurBorderName(r.blurOptions.border)},
               {"kernel", "sampled 2-D Gaussian, radius ceil(4 sigma), normalized to sum 1"},
               {"optimizer", "Adam (beta1 0.9, beta2 0.999)"},
               {"learning_rate", r.blurOptions.learningRate},
               {"max_iterations", r.blurOptions.maxIterations}};
}

// The figures' files, the cluster map's generations and the render comparison.
void addFigures(const EvalResult& r, json& j) {
  j["figures"] = {{"heat_map", kHeatMapFile}, {"elevation", kElevationFile}, {"mean_brightness", kMeanMapFile}};
  if (!r.clusterMapFigure.rgb.empty()) {
    j["figures"]["cluster_map"] = kClusterMapFile;
    j["clusters_per_generation"] = r.clustersPerGeneration;
  } else {
    j["clusters_per_generation"] = nullptr;
  }
  if (r.render.present()) {
    const RenderSection& s = r.render;
    j["render_comparison"] = {{"folder", s.folder},
                              {"scene", s.scene},
                              {"sampling", s.sampling},
                              {"reference", s.reference},
                              {"compressed", s.compressed},
                              {"width", s.width},
                              {"height", s.height},
                              {"space", s.space},
                              {"rmse_all", s.rmseAll},
                              {"rmse_dark10", s.rmseDark},
                              {"rmse_bright10", s.rmseBright},
                              {"error_magnification", s.errorMagnification},
                              {"figures", {kRenderFiles[0], kRenderFiles[1], kRenderFiles[2]}}};
  } else {
    j["render_comparison"] = nullptr;
  }
}

}  // namespace

json reportJson(const EvalResult& r) {
  json j;
  addContext(r, j);
  addHeadline(r, j);
  addSizes(r, j);
  addErrorByDirection(r, j);
  addComparisons(r, j);
  addBlur(r, j);
  addFigures(r, j);
  j["seconds"] = r.seconds;
  return j;
}

// ---- Text formatting (every printed number comes from the JSON)

namespace {

std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}
std::string rmseText(const json& v) { return v.is_null() ? "n/a" : fmt("%#.4g", v.get<double>()); }
std::string srgbText(const json& v) { return v.is_null() ? "n/a" : fmt("%.3f", v.get<double>()); }
std::string psnrText(const json& v) { return v.is_null() ? "infinite (identical)" : fmt("%.2f dB", v.get<double>()); }
std::string sigmaText(const json& v) { return fmt("%.3f", v.get<double>()); }
// A blur estimate's sigma; ">=" when it hit the upper bound (no detail left to measure).
std::string blurSigmaText(const json& b) {
  return (b["at_upper_bound"].get<bool>() ? ">= " : "") + sigmaText(b["sigma"]);
}
std::string degreesText(double v) { return fmt("%g", std::round(v * 1000) / 1000) + "\xC2\xB0"; }
std::string dirText(const json& d) {
  return "(" + degreesText(d["theta"].get<double>()) + ", " + degreesText(d["phi"].get<double>()) + ")";
}
std::string bytesText(const json& v) {
  std::string digits = std::to_string(v.get<std::uint64_t>()), out;
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}
std::string humanBytes(const json& v) {
  double b = v.get<double>();
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  while (b >= 1024 && u < 4) b /= 1024, ++u;
  return u == 0 ? fmt("%.0f B", b) : fmt("%.1f ", b) + units[u];
}
std::string integerText(const json& v) { return std::to_string(v.get<long long>()); }

const char* kLinear = "linear RGB / alpha";
const char* kSrgb = "sRGB 8-bit codes (0-255)";

// Title, material, the compressed file's settings.
void addIntro(Doc& doc, const json& j) {
  doc.title = "BTF evaluation: " + j["method"].get<std::string>();
  const json& m = j["material"];
  std::string intro = "Reference `" + j["reference"].get<std::string>() + "`: " + integerText(m["width"]) + " x " +
                      integerText(m["height"]) + " texels, " + integerText(m["lights"]) + " lights x " +
                      integerText(m["views"]) + " views = " + integerText(m["images"]) + " images.";
  if (!j["compressed"].is_null()) intro += " Compressed file: `" + j["compressed"].get<std::string>() + "`.";
  intro += " alpha = " + fmt("%.6g", m["alpha"].get<double>()) + " (" + m["alpha_source"].get<std::string>() +
           "): every linear value is divided by alpha before the error is taken, as in the paper.";
  doc.paragraph(intro);
  if (!j["details"].empty()) {
    std::vector<std::vector<std::string>> rows;
    for (const auto& [k, v] : j["details"].items()) rows.push_back({k, v.get<std::string>()});
    doc.table({"Setting", "Value"}, rows, "From the compressed file");
  }
}

// Summary.
void addSummary(Doc& doc, const json& j) {
  doc.heading("Summary");
  const bool holdout = !j["rmse_holdout"].is_null();
  std::vector<std::vector<std::string>> rows;
  rows.push_back({"RMSE, all images (eq. 10)", rmseText(j["rmse"]), kLinear});
  if (holdout) {
    rows.push_back({"RMSE, training images", rmseText(j["rmse_training"]), kLinear});
    rows.push_back({"RMSE, held-out images (interpolation, " + integerText(j["holdout_count"]) + " images)",
                    rmseText(j["rmse_holdout"]), kLinear});
  }
  if (j.contains("rmse_ground_truth") && !j["rmse_ground_truth"].is_null()) {
    rows.push_back({"RMSE against the float ground truth, all images", rmseText(j["rmse_ground_truth"]), kLinear});
    if (holdout)
      rows.push_back({"RMSE against the float ground truth, held-out images",
                      rmseText(j["rmse_ground_truth_holdout"]), kLinear});
    rows.push_back({"Noise floor: the stack (" + j["reference_encoding"].get<std::string>() +
                        ") against the float ground truth, all images (" + j["noise_floor_cause"].get<std::string>() +
                        ")",
                    rmseText(j["rmse_reference_vs_ground_truth"]), kLinear});
    if (holdout)
      rows.push_back({"Noise floor, held-out images", rmseText(j["rmse_reference_vs_ground_truth_holdout"]), kLinear});
  }
  rows.push_back({"RMSE, all images", srgbText(j["rmse_srgb8"]), kSrgb});
  if (holdout) rows.push_back({"RMSE, held-out images", srgbText(j["rmse_srgb8_holdout"]), kSrgb});
  rows.push_back({"PSNR, all images", psnrText(j["psnr"]), "linear RGB / alpha, peak 1"});
  rows.push_back({"PSNR, all images", psnrText(j["psnr_srgb8"]), "sRGB 8-bit, peak 255"});
  if (!j["ratio"].is_null())
    rows.push_back({"Compression ratio", "1 : " + fmt("%.0f", j["ratio"].get<double>()), "raw float32 / total"});
  rows.push_back({"Effective blur sigma (median of " + integerText(j["blur"]["image_count"]) + " images)",
                  sigmaText(j["blur_sigma"]), "texels"});
  rows.push_back({"Mean brightness map RMSE (graininess; per-texel means over all images)",
                  rmseText(j["mean_brightness_rmse"]), kLinear});
  if (!j["floor_rmse"].is_null())
    rows.push_back({"Cluster-mean floor, all images (the best any one-value-per-cluster model can do)",
                    rmseText(j["floor_rmse"]), kLinear});
  if (!j["floor_rmse_modulated"].is_null())
    rows.push_back({"Floor with the file's per-texel coefficients (best cluster terms mixed by them)",
                    rmseText(j["floor_rmse_modulated"]), kLinear});
  const json& w = j["worst_pair"];
  rows.push_back({"Worst pair: light " + dirText(w["light"]) + ", view " + dirText(w["view"]), rmseText(w["rmse"]),
                  kLinear});
  doc.table({"Quantity", "Value", "Space / unit"}, rows, "", {false, true, false});
  if (!holdout)
    doc.note("No held-out images are recorded: every image was used in training, so this report has no "
             "interpolation error (RMSE on unseen directions).");
}

// Sizes.
void addSizes(Doc& doc, const json& j) {
  doc.heading("Size (the paper's Table 1)");
  if (j["bytes"].is_null()) {
    doc.note("No size table: this reconstruction does not come from a compressed file.");
  } else if (j["bytes"].contains("gltf_textures")) {
    const json& b = j["bytes"];
    doc.table({"Part", "Bytes", "Size"},
              {{"Raw data (float32 RGB)", bytesText(b["raw_float32"]), humanBytes(b["raw_float32"])},
               {"glTF textures (PNG files)", bytesText(b["gltf_textures"]), humanBytes(b["gltf_textures"])},
               {"**Total**", bytesText(b["total"]), humanBytes(b["total"])},
               {"**Compression ratio** (raw : total)", "1 : " + fmt("%.0f", j["ratio"].get<double>()), ""}},
              "glTF fit: total = the textures (material.gltf and the meshes are not counted). KiB = 1024 bytes.",
              {false, true, true});
  } else if (j["bytes"].contains("pca_basis")) {
    const json& b = j["bytes"];
    const std::string c = integerText(b["pca_components"]);
    std::vector<std::vector<std::string>> srows = {
        {"Raw data (float32 RGB)", bytesText(b["raw_float32"]), humanBytes(b["raw_float32"])},
        {"PCA mean (3 x images, float32)", bytesText(b["pca_mean"]), humanBytes(b["pca_mean"])},
        {"PCA basis (3 x images x " + c + " components, float32)", bytesText(b["pca_basis"]), humanBytes(b["pca_basis"])},
        {"PCA coefficients (texels x " + c + ", float32)", bytesText(b["pca_coefficients"]),
         humanBytes(b["pca_coefficients"])},
        {"**Total**", bytesText(b["total"]), humanBytes(b["total"])},
    };
    if (!b["file"].is_null()) srows.push_back({"File on disk", bytesText(b["file"]), humanBytes(b["file"])});
    srows.push_back({"**Compression ratio** (raw : total)", "1 : " + fmt("%.0f", j["ratio"].get<double>()), ""});
    doc.table({"Part", "Bytes", "Size"}, srows,
              "PCA baseline: total = mean + basis + coefficients (headers, directions and metadata are not counted; "
              "the file on disk is the honest upper bound). KiB = 1024 bytes.",
              {false, true, true});
  } else {
    const json& b = j["bytes"];
    std::vector<std::vector<std::string>> srows = {
        {"Raw data (float32 RGB)", bytesText(b["raw_float32"]), humanBytes(b["raw_float32"])},
        {"Decoder (weights as stored)", bytesText(b["decoder"]), humanBytes(b["decoder"])},
        {"Latents", bytesText(b["latents"]), humanBytes(b["latents"])},
        {"Id list (texel -> cluster)", bytesText(b["ids"]), humanBytes(b["ids"])},
    };
    if (b.contains("planes"))
      srows.push_back({"Direction planes (learned features over light, view, half vector)", bytesText(b["planes"]),
                       humanBytes(b["planes"])});
    if (b.contains("cluster_planes"))
      srows.push_back({"Cluster planes (each cluster's own features over light, view, half vector)",
                       bytesText(b["cluster_planes"]), humanBytes(b["cluster_planes"])});
    if (b.contains("per_texel") && b["per_texel"].get<std::uint64_t>() > 0)
      srows.push_back({"Per-texel factors (modulation codes)", bytesText(b["per_texel"]), humanBytes(b["per_texel"])});
    srows.push_back({"**Total**", bytesText(b["total"]), humanBytes(b["total"])});
    if (!b["file"].is_null()) srows.push_back({"File on disk", bytesText(b["file"]), humanBytes(b["file"])});
    srows.push_back({"**Compression ratio** (raw : total)", "1 : " + fmt("%.0f", j["ratio"].get<double>()), ""});
    if (b.contains("total_paper")) {
      srows.push_back({"Id list with the paper's 4-byte ids", bytesText(b["ids_paper"]), humanBytes(b["ids_paper"])});
      srows.push_back({"Total with 4-byte ids", bytesText(b["total_paper"]), humanBytes(b["total_paper"])});
      srows.push_back({"Compression ratio with 4-byte ids (comparable to the paper)",
                       "1 : " + fmt("%.0f", j["ratio_paper"].get<double>()), ""});
    }
    doc.table({"Part", "Bytes", "Size"}, srows,
              "Total = decoder + latents + id list (+ per-texel factors), the paper's definition (headers, "
              "directions and metadata are not counted; the file on disk is the honest upper bound). KiB = 1024 "
              "bytes.",
              {false, true, true});
  }
}

// Graininess.
void addGraininess(Doc& doc, const json& j) {
  doc.heading("Mean brightness (graininess)");
  doc.paragraph("Each texel's value averaged over all images, for the reference and the reconstruction. A model with "
                "one latent per cluster gives every texel of a cluster the same values, so its map shows the "
                "clusters as flat patches (grain); per-texel factors restore each texel's own brightness. RMSE "
                "between the maps: " + rmseText(j["mean_brightness_rmse"]) + " (linear RGB / alpha).");
  doc.figure(j["figures"]["mean_brightness"].get<std::string>(),
             "Mean brightness: reference | reconstruction | error x " +
                 fmt("%g", j["mean_brightness_error_magnification"].get<double>()) + " (both maps shown brightened x " +
                 fmt("%.3g", j["mean_brightness_display_gain"].get<double>()) + ").",
             "Mean brightness maps");
}

// Cluster map.
void addClusterMap(Doc& doc, const json& j) {
  if (j["figures"].contains("cluster_map")) {
    const json& perGen = j["clusters_per_generation"];
    doc.heading("Cluster map");
    std::string text = "Every texel in the colour of its cluster (shades tell neighbouring clusters apart). ";
    if (perGen.size() > 1) {
      text += "Adaptive clustering (`nbtf compress --adaptive`): the colour is the cluster's split generation, 0 for "
              "the clusters of the initial k-means, +1 for each split in two; the latents went where the high "
              "generations are. Clusters per generation:";
      for (std::size_t g = 0; g < perGen.size(); ++g)
        text += std::string(g ? "," : "") + " " + std::to_string(g) + ": " + std::to_string(perGen[g].get<int>());
      text += ".";
    } else {
      text += "All clusters come from one k-means (fixed k).";
    }
    doc.paragraph(text);
    doc.figure(j["figures"]["cluster_map"].get<std::string>(), "Cluster map (label image).", "Cluster map");
  }
}

// Error by direction.
void addErrorByDirection(Doc& doc, const json& j) {
  const json& w = j["worst_pair"];
  doc.heading("Error by direction");
  doc.figure(j["figures"]["heat_map"].get<std::string>(),
             "RMSE of every image (linear RGB / alpha): lights as rows, views as columns, both grouped into elevation "
             "rings (theta 0 at the top left). Outlined cells are the compared pairs below (#1, #2, ...). Worst: "
             "light " + dirText(w["light"]) + ", view " + dirText(w["view"]) + ", RMSE " + rmseText(w["rmse"]) + ".",
             "RMSE heat map over light and view directions");
  doc.figure(j["figures"]["elevation"].get<std::string>(),
             "RMSE (linear RGB / alpha) of all images whose light (or view) lies on one elevation ring, pooled over "
             "the ring.",
             "RMSE by light and view elevation");
  for (const char* key : {"by_light_elevation", "by_view_elevation"}) {
    bool light = std::string(key) == "by_light_elevation";
    std::vector<std::vector<std::string>> erows;
    for (const auto& e : j[key])
      erows.push_back({degreesText(e["theta"].get<double>()), integerText(e["directions"]), integerText(e["images"]),
                       rmseText(e["rmse"]), srgbText(e["rmse_srgb8"])});
    doc.table({light ? "Light elevation theta" : "View elevation theta", light ? "Lights" : "Views", "Images",
               "RMSE (linear RGB / alpha)", "RMSE (sRGB 8-bit)"},
              erows, light ? "By light elevation" : "By view elevation", {true, true, true, true, true});
  }
}

// Comparisons.
void addComparisons(Doc& doc, const json& j) {
  doc.heading("Image comparisons");
  doc.paragraph("Each strip shows the reference, the reconstruction (both as 8-bit sRGB of their linear values, the "
                "way the source images are stored) and the per-texel error magnified by the factor in its label "
                "(mean over RGB of |reference - reconstruction| / alpha; the colour bar is in unmagnified units).");
  std::vector<std::vector<std::string>> crows;
  std::size_t index = 0;
  for (const auto& c : j["comparisons"]) {
    ++index;
    const json& b = c["blur"];
    std::string pair = c["name"].get<std::string>() + (c["exact"].get<bool>() ? "" : " (nearest measured)");
    crows.push_back({"#" + std::to_string(index), pair, dirText(c["light"]), dirText(c["view"]), rmseText(c["rmse"]),
                     srgbText(c["rmse_srgb8"]), blurSigmaText(b), rmseText(b["rmse_after"]),
                     "x " + fmt("%g", c["error_magnification"].get<double>())});
  }
  doc.table({"", "Pair", "Light", "View", "RMSE (linear RGB / alpha)", "RMSE (sRGB 8-bit)", "Blur sigma (texels)",
             "RMSE after that blur (linear RGB / alpha)", "Error shown"},
            crows, "", {false, false, false, false, true, true, true, true, true});
  index = 0;
  for (const auto& c : j["comparisons"]) {
    ++index;
    doc.heading("#" + std::to_string(index) + " " + c["name"].get<std::string>(), 3);
    std::string where = "Light " + dirText(c["light"]) + ", view " + dirText(c["view"]) + ".";
    if (c["name"] != "worst error") {
      where += c["exact"].get<bool>()
                   ? " Measured exactly as requested."
                   : " Requested light " + dirText(c["requested_light"]) + ", view " + dirText(c["requested_view"]) +
                         ": not measured in this data set, so the nearest measured directions are shown.";
    }
    doc.paragraph(where + " " + c["note"].get<std::string>() + ".");
    doc.figure(c["figure"].get<std::string>(),
               "#" + std::to_string(index) + ": reference | reconstruction | error x " +
                   fmt("%g", c["error_magnification"].get<double>()) + ". RMSE " + rmseText(c["rmse"]) +
                   " (linear RGB / alpha), " + srgbText(c["rmse_srgb8"]) + " (sRGB 8-bit), PSNR " + psnrText(c["psnr"]) +
                   " (linear / alpha, peak 1); effective blur sigma " +
                   blurSigmaText(c["blur"]) + " texels.",
               c["name"].get<std::string>());
  }
}

// Blur.
void addBlur(Doc& doc, const json& j) {
  doc.heading("Effective blur");
  doc.paragraph("Neural BTF reconstructions look blurred. For each image below, sigma is the standard deviation (in "
                "texels) of the Gaussian filter that, applied to the reference, best matches the reconstruction "
                "(least squares in linear RGB / alpha). It is found by gradient descent (Adam, learning rate " +
                fmt("%g", j["blur"]["learning_rate"].get<double>()) +
                ") with the analytic derivative dG/dsigma of the Gaussian; borders " +
                j["blur"]["border"].get<std::string>() +
                ". If the RMSE after the blur is much lower than before, the error is mostly blur; if it barely "
                "drops, it is noise, colour or brightness error. Sigma below about 0.3 texels means no measurable "
                "blur. **Median sigma: " + sigmaText(j["blur_sigma"]) + " texels.**");
  std::vector<std::vector<std::string>> brows;
  for (const auto& s : j["blur"]["images"])
    brows.push_back({dirText(s["light"]), dirText(s["view"]), blurSigmaText(s), rmseText(s["rmse_before"]),
                     rmseText(s["rmse_after"]), integerText(s["iterations"])});
  doc.table({"Light", "View", "Sigma (texels)", "RMSE before (linear RGB / alpha)", "RMSE after blur (linear RGB / alpha)",
             "Adam iterations"},
            brows, "Images: evenly spaced over the stack, the compared pairs and the worst pair",
            {false, false, true, true, true, true});
  for (const auto& s : j["blur"]["images"])
    if (s["at_upper_bound"].get<bool>()) {
      doc.note("\">=\" marks estimates that reached the largest sigma measured (a quarter of the image side, at most "
               "16 texels): those reconstructions keep no detail the reference has at any scale the estimate can see.");
      break;
    }
}

// Rendered comparison (nbtf render --compare).
void addRenderedComparison(Doc& doc, const json& j) {
  if (!j["render_comparison"].is_null()) {
    const json& rc = j["render_comparison"];
    doc.heading("Rendered comparison");
    doc.paragraph("The " + rc["scene"].get<std::string>() + " scene (" + integerText(rc["width"]) + " x " +
                  integerText(rc["height"]) + " pixels, " + rc["sampling"].get<std::string>() +
                  ") rendered by `nbtf render --compare` from the original stack `" +
                  rc["reference"].get<std::string>() + "` and from `" + rc["compressed"].get<std::string>() +
                  "`, as the paper's Tables 3-4 measure compression: RMSE of the whole image and of its darkest "
                  "and brightest 10% of pixels (" + rc["space"].get<std::string>() + ").");
    doc.table({"Region", "RMSE"},
              {{"Whole image", rmseText(rc["rmse_all"])},
               {"Darkest 10%", rmseText(rc["rmse_dark10"])},
               {"Brightest 10%", rmseText(rc["rmse_bright10"])}},
              "Rendered with the same scene, camera and sampling", {false, true});
    const auto& f = rc["figures"];
    doc.figure(f[0].get<std::string>(), "Rendered from the original stack.", "rendered reference");
    doc.figure(f[1].get<std::string>(), "Rendered from the compressed file.", "rendered compressed");
    doc.figure(f[2].get<std::string>(),
               "Absolute difference, magnified x " + fmt("%g", rc["error_magnification"].get<double>()) + ".",
               "rendered error");
  }
}

// Definitions.
void addDefinitions(Doc& doc, const json& j) {
  doc.heading("How these numbers are computed");
  doc.paragraph("**RMSE (linear RGB / alpha)** is eq. (10) of the paper: the square root of the mean squared "
                "difference over every texel, image and colour channel (" + integerText(j["values"]) +
                " values), on linear RGB values divided by alpha, the largest value of the training data, so the "
                "reference lies in [0, 1]. Grouped RMSEs (held-out images, elevation rings, one image) pool the "
                "squared errors of their values; they are not averages of RMSEs.");
  doc.paragraph("**RMSE (sRGB 8-bit)** encodes both the reference and the reconstruction with the sRGB transfer curve "
                "(clamped to [0, 1]) to 8-bit codes 0-255, the units of the JPEG/PNG source images, and takes the "
                "RMSE of the codes. **PSNR** = 20 log10(peak / RMSE) with peak 1 (linear / alpha) or 255 (sRGB 8-bit).");
  doc.paragraph("**Compression ratio** = raw float32 size / total compressed size. All of this is also in "
                "`report.json`, unrounded, under stable keys (docs/evaluation.md).");
}

}  // namespace

// The report as a document: one function per section, in reading order.
Doc reportDoc(const json& j) {
  Doc doc;
  addIntro(doc, j);
  addSummary(doc, j);
  addSizes(doc, j);
  addGraininess(doc, j);
  addClusterMap(doc, j);
  addErrorByDirection(doc, j);
  addComparisons(doc, j);
  addBlur(doc, j);
  addRenderedComparison(doc, j);
  addDefinitions(doc, j);
  return doc;
}

// ---- Writing

namespace {
std::vector<std::uint8_t> writePng(const std::string& path, const Image8& image) {
  writeImage8(path, ImageFormat::Png, image);
  return readFileBytes(path);
}
}  // namespace

ReportPaths writeReport(const EvalResult& r, const std::string& dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) throw fileError(dir, "cannot create the report folder: " + ec.message());
  auto path = [&](const std::string& name) { return (fs::path(dir) / name).string(); };
  ReportPaths out;
  std::map<std::string, std::vector<std::uint8_t>> images;

  // Heat map with the compared pairs outlined.
  std::vector<HeatMapMark> marks;
  for (std::size_t i = 0; i < r.comparisons.size(); ++i)
    marks.push_back({r.comparisons[i].light, r.comparisons[i].view, "#" + std::to_string(i + 1)});
  Image8 heat = renderDirectionHeatMap(r.table.rmseMap(), r.lights, r.views,
                                       {"RMSE per image (linear RGB / alpha)", "light direction", "view direction",
                                        "RMSE (linear RGB / alpha)"},
                                       marks);
  images[kHeatMapFile] = writePng(path(kHeatMapFile), heat);

  ChartSeries byLight{"by light elevation", {}, {}, {224, 123, 57}, {}}, byView{"by view elevation", {}, {}, {42, 111, 151}, {}};
  std::vector<double> ticks;
  for (const auto& e : r.byLightElevation) byLight.x.push_back(e.thetaDeg), byLight.y.push_back(e.error.rmse);
  for (const auto& e : r.byViewElevation) byView.x.push_back(e.thetaDeg), byView.y.push_back(e.error.rmse);
  for (const auto& e : r.byViewElevation) ticks.push_back(std::round(e.thetaDeg));
  Image8 chart = renderLineChart({byLight, byView}, "RMSE by elevation", "elevation theta (degrees)",
                                 "RMSE (linear RGB / alpha)", ChartAxes{ticks.size() > 1 ? ticks : std::vector<double>{}, false, ""});
  images[kElevationFile] = writePng(path(kElevationFile), chart);
  images[kMeanMapFile] = writePng(path(kMeanMapFile), r.meanMapFigure);
  if (!r.clusterMapFigure.rgb.empty()) images[kClusterMapFile] = writePng(path(kClusterMapFile), r.clusterMapFigure);
  if (r.render.present()) {
    images[kRenderFiles[0]] = writePng(path(kRenderFiles[0]), r.render.referenceImage);
    images[kRenderFiles[1]] = writePng(path(kRenderFiles[1]), r.render.compressedImage);
    images[kRenderFiles[2]] = writePng(path(kRenderFiles[2]), r.render.errorImage);
  }

  for (std::size_t i = 0; i < r.comparisons.size(); ++i)
    images[comparisonFile(i)] = writePng(path(comparisonFile(i)), r.comparisons[i].figure);
  for (const auto& [name, bytes] : images) out.figures.push_back(path(name));

  json j = reportJson(r);
  Doc doc = reportDoc(j);
  out.json = path("report.json");
  out.markdown = path("report.md");
  out.html = path("report.html");
  writeFileAtomic(out.json, j.dump(2) + "\n");
  writeFileAtomic(out.markdown, renderMarkdown(doc));
  writeFileAtomic(out.html, renderHtml(doc, images));
  return out;
}

}  // namespace nbtf
