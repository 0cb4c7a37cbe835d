#include "render/compare.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <numeric>
#include <sstream>

#include "util/error.h"

namespace nbtf {

double rmseOf(const float* a, const float* b, std::size_t n) {
  if (n == 0) return 0;
  double s = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double d = double(a[i]) - b[i];
    s += d * d;
  }
  return std::sqrt(s / n);
}

namespace {
double luminance(const float* rgb) { return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]; }

RegionRmse regionRmse(const std::vector<float>& a, const std::vector<float>& b, const std::vector<std::size_t>& pixels) {
  RegionRmse r;
  r.pixels = pixels.size();
  double s = 0;
  for (std::size_t p : pixels)
    for (int c = 0; c < 3; ++c) {
      const double d = double(a[3 * p + c]) - b[3 * p + c];
      s += d * d;
    }
  r.rmse = pixels.empty() ? 0 : std::sqrt(s / (3.0 * pixels.size()));
  return r;
}
}  // namespace

RenderComparison compareImages(const std::vector<float>& reference, const std::vector<float>& test,
                               const std::vector<float>& coverage, int width, int height, double fraction) {
  const std::size_t n = static_cast<std::size_t>(width) * height;
  if (reference.size() != 3 * n || test.size() != 3 * n || coverage.size() != n)
    throw Error("compareImages: the images differ in size");
  RenderComparison c;
  c.all.rmse = rmseOf(reference.data(), test.data(), 3 * n);
  c.all.pixels = n;
  for (std::size_t i = 0; i < 3 * n; ++i) c.maxAbsError = std::max(c.maxAbsError, std::fabs(double(reference[i]) - test[i]));
  std::vector<std::size_t> material;
  for (std::size_t p = 0; p < n; ++p)
    if (coverage[p] >= 0.5f) material.push_back(p);
  if (material.empty()) {
    material.resize(n);
    std::iota(material.begin(), material.end(), 0);
  }
  // Sort by reference luminance (ties by index: deterministic).
  std::stable_sort(material.begin(), material.end(), [&](std::size_t a, std::size_t b) {
    return luminance(&reference[3 * a]) < luminance(&reference[3 * b]);
  });
  const std::size_t k = std::max<std::size_t>(1, static_cast<std::size_t>(std::llround(fraction * material.size())));
  std::vector<std::size_t> dark(material.begin(), material.begin() + k), bright(material.end() - k, material.end());
  c.dark = regionRmse(reference, test, dark);
  c.bright = regionRmse(reference, test, bright);
  c.darkMaxLuminance = luminance(&reference[3 * dark.back()]);
  c.brightMinLuminance = luminance(&reference[3 * bright.front()]);
  return c;
}

std::vector<float> errorImage(const std::vector<float>& reference, const std::vector<float>& test, double magnify) {
  std::vector<float> e(reference.size());
  for (std::size_t i = 0; i < e.size(); ++i) e[i] = static_cast<float>(magnify * std::fabs(double(reference[i]) - test[i]));
  return e;
}

std::string compareMarkdown(const RenderComparison& c, const CompareReportInfo& info) {
  std::ostringstream o;
  o << std::setprecision(4);
  o << "# Rendered comparison: " << info.scene << "\n\n"
    << "- reference (original stack): `" << info.reference << "`\n"
    << "- compressed: `" << info.compressed << "`\n"
    << "- image " << info.width << " x " << info.height << ", sampling " << info.sampling << "; render times "
    << std::fixed << std::setprecision(2) << info.referenceSeconds << " s (reference), " << info.compressedSeconds
    << " s (compressed)\n\n"
    << std::defaultfloat << std::setprecision(4)
    << "RMSE of linear radiance (RGB), as the paper's Tables 3-4; dark / bright = the darkest / brightest 10% of "
       "the pixels showing the material, by the reference's luminance.\n\n"
    << "| region | pixels | RMSE (linear) |\n|---|---:|---:|\n"
    << "| whole image | " << c.all.pixels << " | " << c.all.rmse << " |\n"
    << "| darkest 10% (luminance <= " << c.darkMaxLuminance << ") | " << c.dark.pixels << " | " << c.dark.rmse << " |\n"
    << "| brightest 10% (luminance >= " << c.brightMinLuminance << ") | " << c.bright.pixels << " | " << c.bright.rmse
    << " |\n\n"
    << "Largest absolute difference: " << c.maxAbsError << ".\n\n"
    << "| reference | compressed | error x " << info.magnify << " |\n|---|---|---|\n"
    << "| ![](reference.png) | ![](compressed.png) | ![](error.png) |\n";
  return o.str();
}

std::string compareJson(const RenderComparison& c, const CompareReportInfo& info) {
  nlohmann::json j;
  j["reference"] = info.reference;
  j["compressed"] = info.compressed;
  j["scene"] = info.scene;
  j["width"] = info.width;
  j["height"] = info.height;
  j["sampling"] = info.sampling;
  j["error_magnification"] = info.magnify;
  j["space"] = "linear RGB radiance";
  auto region = [](const RegionRmse& r) { return nlohmann::json{{"rmse", r.rmse}, {"pixels", r.pixels}}; };
  j["rmse"] = {{"all", region(c.all)}, {"dark10", region(c.dark)}, {"bright10", region(c.bright)}};
  j["dark10_max_luminance"] = c.darkMaxLuminance;
  j["bright10_min_luminance"] = c.brightMinLuminance;
  j["max_abs_error"] = c.maxAbsError;
  j["seconds"] = {{"reference", info.referenceSeconds}, {"compressed", info.compressedSeconds}};
  return j.dump(2) + "\n";
}

}  // namespace nbtf
