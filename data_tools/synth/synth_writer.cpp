// writeSynthStack: renders all 81 x 81 light/view pairs of a material and writes them
// in the UBO2003 or UTIA layout, the float ground truth beside them, and synth.json.
//
// Order of work: synth.json is written first marked incomplete (so an interrupted run is
// recognised and replaced by the next one), then the 81 light passes (shadowing) in
// parallel, then the views in parallel - each view renders its 81 light images in order,
// writing every image file and streaming them into the view's ground-truth EXR - and
// finally synth.json again, complete, with the value statistics.
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <regex>
#include <sstream>

#include "io/btf_names.h"
#include "io/color.h"
#include "io/image_io.h"
#include "synth/ground_truth.h"
#include "synth/synth_material.h"
#include "util/atomic_file.h"
#include "util/error.h"
#include "util/parallel.h"
#include "util/progress.h"
#include "util/timer.h"

namespace nbtf::synth {
namespace fs = std::filesystem;

namespace {

constexpr int kJpegQuality = 95;
const char* kJsonName = "synth.json";

std::string formatName(ImageFormat f) { return extensionOf(f).substr(1); }

std::string encodingText(Layout layout, ImageFormat format) {
  if (format == ImageFormat::Jpg) return "8-bit sRGB JPEG, quality " + std::to_string(kJpegQuality);
  if (format == ImageFormat::Png) return "8-bit sRGB PNG";
  (void)layout;
  return "half-float OpenEXR in CIE XYZ (D65), tagged with XYZ chromaticities";
}

// Path of stack image (light, view) for a layout and format.
std::string imagePath(const std::string& outDir, Layout layout, ImageFormat format, int light, int view) {
  const auto& dirs = hemisphere81();
  const Direction& l = dirs[light];
  const Direction& v = dirs[view];
  std::string name = layout == Layout::Ubo2003
                         ? ubo2003FileName(light * static_cast<int>(dirs.size()) + view, l, v, extensionOf(format))
                         : utiaFileName(l, v, extensionOf(format));
  return (fs::path(outDir) / viewFolderName(v) / name).string();
}

std::string groundTruthPath(const std::string& outDir, int view) { return nbtf::groundTruthPath(outDir, hemisphere81()[view]); }

// linearToSrgb8 without a pow per value, giving identical codes: the 255 linear
// thresholds where the 8-bit code steps up are found by bisection on linearToSrgb8
// itself; a table over the float's exponent and top 8 mantissa bits then holds the code
// at the start of each bucket and the one threshold inside it (buckets are narrower than
// the code steps, so there is never more than one).
class Srgb8Encoder {
 public:
  Srgb8Encoder() {
    float thresholds[256];
    thresholds[0] = 0;
    for (int code = 1; code < 256; ++code) {
      float lo = 0, hi = 1;  // invariant: linearToSrgb8(lo) < code <= linearToSrgb8(hi)
      for (int i = 0; i < 200; ++i) {
        float mid = 0.5f * (lo + hi);
        if (mid <= lo || mid >= hi) break;
        (linearToSrgb8(mid) >= code ? hi : lo) = mid;
      }
      thresholds[code] = hi;
    }
    if (!(thresholds[1] > bucketValue(0))) throw Error("sRGB encoder: first threshold below the table");
    for (std::uint32_t b = 0; b < kBuckets; ++b) {
      float from = bucketValue(b), to = bucketValue(b + 1);
      int code = static_cast<int>(std::upper_bound(thresholds, thresholds + 256, from) - thresholds) - 1;
      code_[b] = static_cast<std::uint8_t>(code);
      step_[b] = std::numeric_limits<float>::infinity();
      if (code < 255 && thresholds[code + 1] < to) {
        step_[b] = thresholds[code + 1];
        if (code + 2 < 256 && thresholds[code + 2] < to) throw Error("sRGB encoder: two code steps in one bucket");
      }
    }
  }
  std::uint8_t operator()(float linear) const {
    if (!(linear > 0)) return 0;
    if (linear >= 1) return 255;
    std::uint32_t bits;
    std::memcpy(&bits, &linear, sizeof bits);
    if (bits < kFirstBits) return 0;
    std::uint32_t b = (bits - kFirstBits) >> kShift;
    return static_cast<std::uint8_t>(code_[b] + (linear >= step_[b]));
  }

 private:
  static constexpr std::uint32_t kShift = 15;              // keep exponent + 8 mantissa bits
  static constexpr std::uint32_t kFirstBits = 107u << 23;  // 2^-20: codes are 0 below ~1.5e-4
  static constexpr std::uint32_t kBuckets = ((127u << 23) - kFirstBits) >> kShift;  // up to 1.0
  static float bucketValue(std::uint32_t b) {
    std::uint32_t bits = kFirstBits + (b << kShift);
    float v;
    std::memcpy(&v, &bits, sizeof v);
    return v;
  }
  std::uint8_t code_[kBuckets];
  float step_[kBuckets];
};

void writeImageFile(const std::string& path, ImageFormat format, int width, int height, const float* rgb) {
  if (format == ImageFormat::Exr) {
    writeExr(path, width, height, rgb, true, ExrColorSpace::CieXyz);
    return;
  }
  static const Srgb8Encoder encode;
  Image8 image;
  image.width = width, image.height = height;
  image.rgb.resize(static_cast<std::size_t>(width) * height * 3);
  for (std::size_t i = 0; i < image.rgb.size(); ++i) image.rgb[i] = encode(rgb[i]);
  writeImage8(path, format, image, kJpegQuality);
}

// ---- Output folder --------------------------------------------------------------------------

// Removes what an earlier run described by `jsonPath` wrote (and nothing else).
void removeEarlierOutput(const std::string& outDir, const std::string& jsonPath) {
  nlohmann::json old;
  try {
    std::ifstream in(jsonPath);
    old = nlohmann::json::parse(in);
    Layout layout = parseLayout(old.at("layout").get<std::string>());
    ImageFormat format = parseImageFormat(old.at("format").get<std::string>());
    const int n = static_cast<int>(hemisphere81().size());
    std::error_code ec;
    for (int view = 0; view < n; ++view) {
      for (int light = 0; light < n; ++light) fs::remove(imagePath(outDir, layout, format, light, view), ec);
      fs::remove(groundTruthPath(outDir, view), ec);
      // Temporary files of an interrupted run: ".<name>.tmp<pid>_<n>.<ext>".
      for (const fs::path& folder : {fs::path(outDir) / viewFolderName(hemisphere81()[view]),
                                    fs::path(outDir) / kGroundTruthFolder}) {
        if (!fs::is_directory(folder, ec)) continue;
        std::vector<fs::path> stale;
        for (const auto& e : fs::directory_iterator(folder, ec)) {
          std::string name = e.path().filename().string();
          if (name.size() > 1 && name[0] == '.' && name.find(".tmp") != std::string::npos) stale.push_back(e.path());
        }
        for (const auto& p : stale) fs::remove(p, ec);
      }
      fs::remove(fs::path(outDir) / viewFolderName(hemisphere81()[view]), ec);  // only if now empty
    }
    fs::remove(fs::path(outDir) / kGroundTruthFolder, ec);
    fs::remove(jsonPath, ec);
  } catch (const Error& e) {
    throw fileError(jsonPath, std::string("cannot replace the earlier output it describes: ") + e.what());
  } catch (const std::exception& e) {
    throw fileError(jsonPath, std::string("is not a readable nbtf-synth description (") + e.what() +
                                  "); remove the folder or choose another");
  }
}

void prepareOutputFolder(const std::string& outDir) {
  if (outDir.empty()) throw Error("the output folder path is empty");
  std::error_code ec;
  if (fs::exists(outDir, ec) && !fs::is_directory(outDir, ec)) throw fileError(outDir, "exists and is not a folder");
  if (!fs::exists(outDir, ec)) {
    fs::create_directories(outDir, ec);
    if (ec) throw fileError(outDir, "cannot create output folder: " + ec.message());
    return;
  }
  std::string json = (fs::path(outDir) / kJsonName).string();
  if (fs::exists(json, ec)) {
    removeEarlierOutput(outDir, json);
    return;
  }
  if (fs::directory_iterator(outDir, ec) != fs::directory_iterator())
    throw fileError(outDir, "output folder is not empty and holds no synth.json from an earlier nbtf-synth run; "
                            "choose an empty or new folder (nbtf-synth only replaces its own output)");
  if (ec) throw fileError(outDir, "cannot list output folder: " + ec.message());
}

// ---- Description -----------------------------------------------------------------------------

nlohmann::json describe(const SynthOptions& o, const SynthSummary* summary) {
  using nlohmann::json;
  json dirs = json::array();
  for (const Direction& d : hemisphere81()) dirs.push_back({d.thetaDeg, d.phiDeg});
  json j;
  j["generator"] = "nbtf-synth";
  j["complete"] = summary != nullptr;
  j["preset"] = o.preset;
  j["description"] = presetDescription(o.preset);
  j["width"] = o.width;
  j["height"] = o.height;
  j["seed"] = o.seed;
  j["layout"] = layoutName(o.layout);
  j["format"] = formatName(o.format);
  j["encoding"] = encodingText(o.layout, o.format);
  j["render"] = {{"parallax", o.render.parallax},
                 {"shadows", o.render.shadows},
                 {"interreflection", o.render.interreflection},
                 {"supersampling", o.render.supersampling}};
  j["frame"] = "directions (theta, phi) in degrees; theta from the surface normal; phi = 0 toward the image's "
               "right, phi = 90 toward its top; distant light of unit irradiance at normal incidence, orthographic view";
  j["lights"] = dirs;
  j["views"] = dirs;
  j["images"] = static_cast<int>(dirs.size() * dirs.size());
  j["files"] = o.layout == Layout::Ubo2003
                   ? "<view folder>/IIIII tlTTT plPPP tvTTT pvPPP" + extensionOf(o.format) +
                         ", IIIII = 81 * light index + view index"
                   : "<view folder>/tlTTT_plPPP_tvTTT_pvPPP" + extensionOf(o.format);
  j["view_folder"] = "tvTTT_pvPPP";
  if (o.groundTruth)
    j["ground_truth"] = {{"folder", kGroundTruthFolder},
                         {"files", "<view folder>.exr"},
                         {"encoding", "float32 OpenEXR, linear sRGB (Rec. 709 chromaticities)"},
                         {"arrangement", "the 81 light images of the view stacked top to bottom in light order; "
                                         "height = 81 * " + std::to_string(o.height)}};
  if (summary)
    j["values"] = {{"space", "linear sRGB, exact (before 8-bit or half-float encoding)"},
                   {"min", summary->minValue},
                   {"max", summary->maxValue},
                   {"mean", summary->meanValue},
                   {"clipped_fraction", summary->clippedFraction},
                   {"clipped_note", "fraction of samples above 1, which clip in 8-bit files"}};
  return j;
}

void writeDescription(const std::string& outDir, const SynthOptions& o, const SynthSummary* summary) {
  // Indented for people, but each [theta, phi] pair on one line.
  static const std::regex pair(R"(\[\s*([-0-9.eE+]+),\s*([-0-9.eE+]+)\s*\])");
  std::string text = std::regex_replace(describe(o, summary).dump(2), pair, "[$1, $2]");
  writeFileAtomic((fs::path(outDir) / kJsonName).string(), text + "\n");
}

// Value statistics of one view, reduced in view order afterwards (deterministic).
struct ViewStats {
  float lo = std::numeric_limits<float>::infinity(), hi = -std::numeric_limits<float>::infinity();
  double sum = 0;
  std::size_t clipped = 0, count = 0;
  void add(const float* v, std::size_t n, const std::string& image) {
    for (std::size_t i = 0; i < n; ++i) {
      if (!std::isfinite(v[i]) || v[i] < 0)  // a renderer bug: never write it silently
        throw fileError(image, "rendered value " + std::to_string(v[i]) + " at texel " + std::to_string(i / 3) +
                                   " is not finite and non-negative");
      lo = std::min(lo, v[i]), hi = std::max(hi, v[i]);
      sum += v[i];
      clipped += v[i] > 1.0f;
    }
    count += n;
  }
};

}  // namespace

// ---- Options ---------------------------------------------------------------------------------

void validateSynthOptions(const SynthOptions& o) {
  presetDescription(o.preset);  // throws on an unknown preset
  for (auto [size, what] : {std::pair<int, const char*>{o.width, "width"}, {o.height, "height"}})
    if (size < kMinSize || size > kMaxSize)
      throw Error(std::string("size: ") + what + " " + std::to_string(size) + " is out of range (" +
                  std::to_string(kMinSize) + " to " + std::to_string(kMaxSize) + " texels)");
  if (o.render.supersampling < 1 || o.render.supersampling > 4)
    throw Error("supersampling " + std::to_string(o.render.supersampling) + " is out of range (1 to 4)");
  // Each layout is written as its data set ships: UBO2003 as JPEG only, UTIA as PNG or EXR.
  if (o.layout == Layout::Ubo2003 && o.format != ImageFormat::Jpg)
    throw Error("layout ubo2003 is written as JPEG only (as the UBO2003 data set ships); got format " +
                formatName(o.format) + " - use --layout utia for png or exr");
  if (o.layout == Layout::Utia && o.format == ImageFormat::Jpg)
    throw Error("layout utia is written as png or exr (as the UTIA data set ships); got format jpg - use "
                "--layout ubo2003 for JPEG");
  if (o.layout == Layout::Unknown || o.layout == Layout::Ubo2014)
    throw Error("layout must be ubo2003 or utia (ubo2014 files are written by writeSynthUbo2014)");
}

// ---- Writing ------------------------------------------------------------------------------------

SynthSummary writeSynthStack(const SynthOptions& options, const std::string& outDir) {
  auto start = std::chrono::steady_clock::now();
  validateSynthOptions(options);
  prepareOutputFolder(outDir);
  writeDescription(outDir, options, nullptr);
  if (options.groundTruth) {
    std::error_code ec;
    fs::create_directories(fs::path(outDir) / kGroundTruthFolder, ec);
    if (ec) throw fileError((fs::path(outDir) / kGroundTruthFolder).string(), "cannot create folder: " + ec.message());
  }

  SynthMaterial material(options.preset, options.width, options.height, options.seed, options.render);
  const auto& dirs = hemisphere81();
  const int n = static_cast<int>(dirs.size());
  const int w = options.width, h = options.height;
  const std::size_t imageFloats = static_cast<std::size_t>(w) * h * 3;

  std::vector<std::shared_ptr<const SynthMaterial::LightPass>> lights(n);
  {
    Progress progress("shadows", n, options.progress);
    parallelForDynamic(n, [&](std::size_t l, int) {
      lights[l] = material.prepareLight(dirs[l]);
      progress.advance();
    });
  }

  std::vector<ViewStats> stats(n);
  Progress progress("render", static_cast<std::size_t>(n) * n, options.progress);
  // Grazing views march longest: hand them out first so the last views to finish are short.
  parallelForDynamic(n, [&](std::size_t k, int) {
    const int view = n - 1 - static_cast<int>(k);
    auto viewPass = material.prepareView(dirs[view]);
    std::error_code ec;
    fs::path folder = fs::path(outDir) / viewFolderName(dirs[view]);
    fs::create_directories(folder, ec);
    if (ec) throw fileError(folder.string(), "cannot create folder: " + ec.message());
    std::vector<float> rgb(imageFloats);
    auto renderAll = [&](GroundTruthWriter* truth) {
      for (int light = 0; light < n; ++light) {
        material.render(*lights[light], *viewPass, rgb.data());
        std::string path = imagePath(outDir, options.layout, options.format, light, view);
        stats[view].add(rgb.data(), rgb.size(), path);
        writeImageFile(path, options.format, w, h, rgb.data());
        if (truth) truth->append(rgb.data());
        progress.advance();
      }
    };
    if (!options.groundTruth) {
      renderAll(nullptr);
      return;
    }
    std::string comment = "nbtf-synth ground truth: preset " + options.preset + ", seed " +
                          std::to_string(options.seed) + ", view " + viewFolderName(dirs[view]) +
                          ", 81 light images top to bottom, linear sRGB";
    writeAtomicVia(groundTruthPath(outDir, view), [&](const std::string& tmp) {
      GroundTruthWriter truth(tmp, w, h, n, comment);
      renderAll(&truth);
    });
  });
  progress.finish();

  SynthSummary summary;
  summary.images = n * n;
  summary.groundTruthFiles = options.groundTruth ? n : 0;
  ViewStats all;
  for (const ViewStats& s : stats) {
    all.lo = std::min(all.lo, s.lo), all.hi = std::max(all.hi, s.hi);
    all.sum += s.sum, all.clipped += s.clipped, all.count += s.count;
  }
  summary.minValue = all.lo, summary.maxValue = all.hi;
  summary.meanValue = all.sum / static_cast<double>(all.count);
  summary.clippedFraction = static_cast<double>(all.clipped) / static_cast<double>(all.count);
  writeDescription(outDir, options, &summary);
  summary.seconds = secondsSince(start);
  return summary;
}

std::vector<float> readGroundTruthImage(const std::string& outDir, int light, int view) {
  const int n = static_cast<int>(hemisphere81().size());
  if (light < 0 || light >= n || view < 0 || view >= n)
    throw Error("ground truth image (light " + std::to_string(light) + ", view " + std::to_string(view) +
                ") is out of range (0 to " + std::to_string(n - 1) + ")");
  std::string path = groundTruthPath(outDir, view);
  std::error_code ec;
  if (!fs::exists(path, ec)) throw fileError(path, "no such ground truth file (written without ground truth?)");
  return readGroundTruthBlock(path, light, n);
}

}  // namespace nbtf::synth
