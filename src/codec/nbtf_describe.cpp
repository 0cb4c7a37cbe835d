#include "codec/nbtf_describe.h"

#include <cstdio>
#include <string>
#include <nlohmann/json.hpp>
#include <sstream>

#include "codec/methods/method.h"

namespace nbtf {
namespace {

std::string number(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// One metadata value as text, or "" when absent / not a number.
std::string jsonNumber(const nlohmann::json& j, const char* a, const char* b = nullptr) {
  const nlohmann::json* v = &j;
  for (const char* key : {a, b}) {
    if (!key) break;
    if (!v->is_object() || !v->contains(key)) return "";
    v = &(*v)[key];
  }
  return v->is_number() ? number(v->get<double>()) : "";
}

}  // namespace

std::string describeNbtf(const CompressedBtf& btf, const std::string& path, std::uint64_t fileBytes) {
  std::ostringstream o;
  char line[512];
  auto field = [&](const char* name, const std::string& value) {
    std::snprintf(line, sizeof line, "%-15s%s\n", name, value.c_str());
    o << line;
  };
  field("file", path + " (.nbtf format " + std::to_string(btf.formatMajor) + "." + std::to_string(btf.formatMinor) + ")");
  const MethodKind& kind = methodKind(btf.method, path);
  field("method", kind.summary(btf));
  std::string texels = std::to_string(btf.width) + " x " + std::to_string(btf.height) + " = " +
                       std::to_string(btf.numTexels());
  if (!btf.crop.empty())
    texels += " (crop " + std::to_string(btf.crop.x) + "," + std::to_string(btf.crop.y) + "," +
              std::to_string(btf.crop.width) + "," + std::to_string(btf.crop.height) + " of " +
              std::to_string(btf.sourceWidth) + " x " + std::to_string(btf.sourceHeight) + " source images)";
  field("texels", texels);
  field("images", std::to_string(btf.numImages()) + " (" + std::to_string(btf.lights.size()) + " lights x " +
                      std::to_string(btf.views.size()) + " views)");
  field("source", "layout " + layoutName(btf.layout) + ", " + sampleTypeName(btf.sourceSampleType));
  for (const auto& [name, value] : kind.infoFields(btf)) field(name.c_str(), value);
  if (btf.holdoutImages.empty()) {
    field("hold-out", btf.isPca() ? "none (every image was used in the PCA fit)"
                                  : "none (every image was used for training)");
  } else {
    std::snprintf(line, sizeof line, "%zu images (%.1f%%) kept out of %s", btf.holdoutImages.size(),
                  100.0 * btf.holdoutImages.size() / btf.numImages(),
                  btf.isPca() ? "the PCA fit (their rows are interpolated)" : "training");
    field("hold-out", line);
  }
  if (!btf.isPca())
    field("encoder", btf.encoderState.empty() ? "not stored"
                                            : "stored (" + std::to_string(btf.encoderState.size()) + " bytes)");
  if (!btf.skippedSections.empty()) {
    std::string s;
    for (const auto& t : btf.skippedSections) s += (s.empty() ? "" : ", ") + t;
    field("skipped", "optional sections unknown to this nbtf: " + s);
  }

  // Training statistics recorded by `nbtf compress` (see pipeline/compress_parts.cpp for the keys).
  nlohmann::json meta = nlohmann::json::parse(btf.metadataJson, nullptr, /*allow_exceptions=*/false);
  std::string train = jsonNumber(meta, "training", "rmse_train");
  if (!train.empty()) {
    std::string holdout = jsonNumber(meta, "training", "rmse_holdout");
    std::string text = "RMSE " + train + (btf.isPca() ? " on fitted images" : " on training images");
    if (!holdout.empty()) text += ", " + holdout + " on held-out images";
    field(btf.isPca() ? "fit" : "training", text + " (linear RGB / alpha, eq. 10)");
    std::string epochs = jsonNumber(meta, "training", "epochs");
    std::string seed = jsonNumber(meta, "seed");
    std::string threads = jsonNumber(meta, "threads");
    std::string run;
    if (!epochs.empty()) run += epochs + " epochs";
    if (!seed.empty()) run += (run.empty() ? "" : ", ") + std::string("seed ") + seed;
    if (!threads.empty()) run += (run.empty() ? "" : ", ") + threads + " threads";
    if (meta.contains("config") && meta["config"].is_object() && meta["config"].contains("optimizer") &&
        meta["config"]["optimizer"].is_string())
      run += (run.empty() ? "" : ", ") + meta["config"]["optimizer"].get<std::string>();
    if (!run.empty()) field("run", run);
  }
  std::string pcaExplained = jsonNumber(meta, "pca", "explained_variance_ratio");
  if (btf.isPca() && !pcaExplained.empty()) {
    std::snprintf(line, sizeof line, "%.2f%%", 100 * std::stod(pcaExplained));
    field("pca", std::to_string(btf.latentDim) + " components explain " + line +
                     " of the variance of the fitted ABRDFs (linear RGB / alpha)");
  }
  std::string explained = jsonNumber(meta, "clustering", "pca_explained_variance_ratio");
  if (!explained.empty()) {
    // The number itself, not its text: "%.6g" of a subnormal does not read back (std::stod
    // throws), and the metadata is the file's, so untrusted.
    std::snprintf(line, sizeof line, "%.1f%%",
                  100 * meta["clustering"]["pca_explained_variance_ratio"].get<double>());
    // Files written before the space was an option clustered the standardized log ABRDFs.
    const auto& c = meta["clustering"];
    const bool linear = c.contains("space") && c["space"] == "linear";
    field("clustering", "PCA with " + jsonNumber(meta, "clustering", "pca_components") + " components explains " +
                            line + " of the variance (" +
                            (linear ? "linear ABRDFs / alpha" : "standardized log ABRDFs") + "); k-means " +
                            jsonNumber(meta, "clustering", "kmeans_iterations") + " iterations");
  }
  o << "\n" << formatSizeTable(computeSizes(btf, fileBytes));
  return o.str();
}

}  // namespace nbtf
