#include "gltf/gltf_export.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>

#include "codec/decoder.h"
#include "codec/nbtf_file.h"
#include "io/btf_loader.h"
#include "io/ground_truth.h"
#include "util/error.h"

namespace nbtf::gltf {
namespace {

bool sameDirections(const std::vector<Direction>& a, const std::vector<Direction>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (std::abs(a[i].thetaDeg - b[i].thetaDeg) > 1e-3 || std::abs(a[i].phiDeg - b[i].phiDeg) > 1e-3) return false;
  return true;
}

// What the export reads: the material's images (to fit) and the references to measure against.
struct Inputs {
  std::vector<Direction> lights, views;
  int width = 0, height = 0;
  double alpha = 0;
  ImageSource fitSource;
  std::vector<Reference> references;
  std::shared_ptr<BtfStack> stack;
  std::shared_ptr<NbtfDecoder> decoder;
};

std::shared_ptr<BtfStack> loadStack(const std::string& path, const ExportOptions& o) {
  LoadOptions load;
  load.crop = o.crop;
  load.progress = o.progress;
  return std::make_shared<BtfStack>(loadBtfStack(resolveBtfInput(path, load), load));
}

void addStackReferences(Inputs& in, const std::string& path, const ExportOptions& o) {
  std::shared_ptr<BtfStack> stack = in.stack;
  in.references.push_back({"stack", path, [stack](int image, float* rgb) { stack->imageLinear(image, rgb); }});
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec) && hasGroundTruth(path, stack->views()))
    in.references.push_back({"ground_truth", (std::filesystem::path(path) / kGroundTruthFolder).string(),
                             groundTruthSource(path, stack->lights(), stack->views(), o.crop, stack->width(),
                                               stack->height())});
}

Inputs openInputs(const std::string& input, const ExportOptions& o) {
  Inputs in;
  if (hasNbtfMagic(input)) {
    if (!o.crop.empty()) throw Error("--crop applies to image stacks; " + input + " is a .nbtf file");
    in.decoder = std::make_shared<NbtfDecoder>(NbtfDecoder::open(input));
    std::shared_ptr<NbtfDecoder> d = in.decoder;
    in.lights = d->lights(), in.views = d->views(), in.width = d->width(), in.height = d->height();
    in.alpha = d->alpha();
    const std::size_t nv = in.views.size();
    const std::vector<Direction> lights = in.lights, views = in.views;
    in.fitSource = [d, lights, views, nv](int image, float* rgb) {
      d->decodeImage(lights[image / nv], views[image % nv], rgb, OutputScale::Linear);
    };
    if (!o.reference.empty()) {
      in.stack = loadStack(o.reference, o);
      if (in.stack->width() != in.width || in.stack->height() != in.height ||
          !sameDirections(in.stack->lights(), in.lights) || !sameDirections(in.stack->views(), in.views))
        throw fileError(o.reference, "is not the stack '" + input + "' was made from (its size or directions differ)");
      addStackReferences(in, o.reference, o);
    }
    in.references.push_back({"nbtf", input, in.fitSource});
  } else {
    if (!o.reference.empty()) throw Error("--reference applies to a .nbtf input; " + input + " is a stack");
    in.stack = loadStack(input, o);
    std::shared_ptr<BtfStack> s = in.stack;
    in.lights = s->lights(), in.views = s->views(), in.width = s->width(), in.height = s->height();
    float lo = 0, hi = 0;
    s->valueRange(lo, hi);
    in.alpha = hi;
    in.fitSource = [s](int image, float* rgb) { s->imageLinear(image, rgb); };
    addStackReferences(in, input, o);
  }
  if (!(in.alpha > 0)) throw fileError(input, "holds no positive value: there is no material to fit");
  return in;
}

nlohmann::json errorJson(const FitError& e) {
  nlohmann::json j = {{"source", e.source}, {"rmse", e.rmse}};
  for (const auto& [key, bands] : {std::pair{"by_light_elevation", &e.byLight}, std::pair{"by_view_elevation", &e.byView}})
    for (const ElevationBand& b : *bands)
      j[key].push_back({{"theta_from_deg", b.thetaFromDeg}, {"theta_to_deg", b.thetaToDeg}, {"rmse", b.rmse}});
  return j;
}

}  // namespace

ExtensionMode parseExtensionMode(const std::string& text, const std::string& option) {
  if (text == "auto") return ExtensionMode::Auto;
  if (text == "on") return ExtensionMode::On;
  if (text == "off") return ExtensionMode::Off;
  throw Error(option + " must be auto, on or off, got '" + text + "'");
}
std::string extensionModeName(ExtensionMode mode) {
  return mode == ExtensionMode::Auto ? "auto" : mode == ExtensionMode::On ? "on" : "off";
}

ExportSummary exportGltf(const std::string& input, const std::string& outputDir, const ExportOptions& o) {
  checkFitOptions(o.fit);
  checkGltfOutput(outputDir);
  const Inputs in = openInputs(input, o);
  ExportSummary s;
  s.input = input, s.output = outputDir;
  s.width = in.width, s.height = in.height, s.images = static_cast<int>(in.lights.size() * in.views.size());
  s.alpha = in.alpha;
  FitOptions fit = o.fit;
  fit.progress = o.progress;
  const FitData data = gatherFitData(in.width, in.height, in.lights, in.views, in.fitSource, fit);
  s.exposure = chooseExposure(data);
  // Candidates are measured on the 8-bit textures a renderer reads, not on the fit's doubles.
  struct Candidate {
    bool sheen = false, specular = false;
    TextureSet textures;
    FitSummary fit;
  };
  auto fitWith = [&](bool sheen, bool specular) {
    Candidate c{sheen, specular, {}, {}};
    FitOptions f = fit;
    f.sheen = sheen, f.specular = specular;
    GltfMaterial m = fitMaterial(data, s.exposure, f, &c.fit);
    m.sheen = sheen, m.specular = specular;
    c.textures = quantize(m);
    return c;
  };
  const std::vector<Reference> own = {in.references.back().name == "nbtf" ? in.references.back() : in.references.front()};
  auto rmseOf = [&](const TextureSet& t) {
    return measureFitErrors(dequantize(t, s.exposure, outputDir), in.lights, in.views, own, in.alpha, o.progress)[0].rmse;
  };
  Candidate best = fitWith(o.sheen == ExtensionMode::On, o.specular == ExtensionMode::On);
  double seconds = best.fit.seconds, bestRmse = -1;
  for (const char* ext : {"KHR_materials_specular", "KHR_materials_sheen"}) {
    const bool isSheen = std::string(ext) == "KHR_materials_sheen";
    if ((isSheen ? o.sheen : o.specular) != ExtensionMode::Auto) continue;
    if (bestRmse < 0) bestRmse = rmseOf(best.textures);
    Candidate c = fitWith(best.sheen || isSheen, best.specular || !isSheen);
    seconds += c.fit.seconds;
    ExtensionTrial trial{ext, bestRmse, rmseOf(c.textures), false};
    if (trial.with < (1 - kExtensionMinGain) * trial.without) best = c, bestRmse = trial.with, trial.kept = true;
    s.trials.push_back(trial);
  }
  s.fit = best.fit;
  s.fit.seconds = seconds;
  s.sheen = best.sheen, s.specular = best.specular;
  const TextureSet& textures = best.textures;
  const GltfMaterial stored = dequantize(textures, s.exposure, outputDir);
  const auto start = std::chrono::steady_clock::now();
  s.errors = measureFitErrors(stored, in.lights, in.views, in.references, in.alpha, o.progress);
  s.measureSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const std::string name = std::filesystem::path(input).filename().string();
  s.bytes = writeGltfExport(outputDir, textures, s.exposure, name.empty() ? "nbtf material" : name, fitReportJson(s, o));
  const double raw = double(s.images) * s.width * s.height * 3 * 4;
  s.ratio = s.bytes.total() ? raw / double(s.bytes.total()) : 0;
  return s;
}

std::string fitReportJson(const ExportSummary& s, const ExportOptions& o) {
  nlohmann::json j;
  j["input"] = s.input;
  j["model"] = "glTF 2.0 metallic-roughness (Appendix B BRDF) with a tangent-space normal map, per texel";
  j["convention"] = "value = exposure x f(l, v) x max(0, n_shading . l); light the material with a sun of strength "
                    "`exposure` to reproduce the BTF's values";
  j["exposure"] = s.exposure;
  j["width"] = s.width, j["height"] = s.height, j["images"] = s.images;
  j["alpha"] = s.alpha;
  j["error_space"] = "linear RGB / alpha (alpha = the input's largest value), over every texel and image";
  j["raw_bytes"] = double(s.images) * s.width * s.height * 3 * 4;
  j["fit"] = {{"images_fitted", s.fit.texels ? std::min(o.fit.samples, s.images) : 0},
              {"peak_margin", kPeakMargin},
              {"min_roughness", o.fit.minRoughness},
              {"refitted_texels", s.fit.refitted},
              {"iterations", o.fit.iterations},
              {"seed", o.fit.seed},
              {"max_tilt_deg", o.fit.maxTiltDeg},
              {"seconds", s.fit.seconds},
              {"fitting_images_rmse_linear", s.fit.sampleRmse}};
  j["measure_seconds"] = s.measureSeconds;
  j["extensions"]["KHR_materials_sheen"] = {{"mode", extensionModeName(o.sheen)}, {"written", s.sheen}};
  j["extensions"]["KHR_materials_specular"] = {{"mode", extensionModeName(o.specular)}, {"written", s.specular}};
  for (const ExtensionTrial& t : s.trials)
    j["extensions"][t.name]["rmse_without"] = t.without, j["extensions"][t.name]["rmse_with"] = t.with;
  for (const FitError& e : s.errors) j["rmse"][e.name] = errorJson(e);
  return j.dump();
}

std::string formatExportSummary(const ExportSummary& s) {
  std::string out;
  char line[256];
  std::snprintf(line, sizeof line, "wrote %s: material.gltf, %d textures (%.1f KiB, 1 : %.0f raw float32), fit_report.json\n",
                s.output.c_str(), 3 + int(s.sheen) + int(s.specular), s.bytes.total() / 1024.0, s.ratio);
  out += line;
  std::snprintf(line, sizeof line, "fit: %d x %d texels in %.1f s; exposure (sun strength) %.4g; specular %s, sheen %s\n",
                s.width, s.height, s.fit.seconds, s.exposure, s.specular ? "written" : "not written",
                s.sheen ? "written" : "not written");
  out += line;
  for (const ExtensionTrial& t : s.trials) {
    std::snprintf(line, sizeof line, "%s: RMSE vs the input %.5f with, %.5f without: %s\n", t.name.c_str(), t.with,
                  t.without, t.kept ? "kept" : "not kept (gains under 1%)");
    out += line;
  }
  for (const FitError& e : s.errors) {
    std::snprintf(line, sizeof line, "RMSE vs %-12s %.5f (linear / alpha, all %d images)\n", e.name.c_str(), e.rmse,
                  s.images);
    out += line;
  }
  return out;
}

}  // namespace nbtf::gltf
