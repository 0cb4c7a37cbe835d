#include "io/source_fingerprint.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "util/error.h"
#include "util/hex.h"

namespace nbtf {
namespace {

using json = nlohmann::json;

constexpr int kPatternGrid = 16;

// The sampled texels of the pattern (texel indices), for a stack of this size.
std::vector<int> patternTexels(int width, int height, int& gridX, int& gridY) {
  gridX = std::min(kPatternGrid, width), gridY = std::min(kPatternGrid, height);
  std::vector<int> texels;
  for (int j = 0; j < gridY; ++j)
    for (int i = 0; i < gridX; ++i) {
      const int x = static_cast<int>((2LL * i + 1) * width / (2 * gridX));
      const int y = static_cast<int>((2LL * j + 1) * height / (2 * gridY));
      texels.push_back(y * width + x);
    }
  return texels;
}

// What the fingerprint holds, measured on a stack in one read of each image: per image the mean
// linear RGB over the texels, and per sampled texel the median linear luminance over the
// images (the median, so that the few images whose highlights clip in an 8-bit copy of the
// stack do not move it).
struct Measured {
  std::vector<std::array<double, 3>> means;
  std::vector<double> pattern;
};
Measured measure(const BtfStack& stack, const std::vector<int>& images, const std::vector<int>& texels) {
  Measured m;
  std::vector<std::vector<double>> values(texels.size());
  std::vector<float> buffer(static_cast<std::size_t>(stack.numTexels()) * 3);
  for (int image : images) {
    if (image >= stack.numImages())
      throw Error("the source fingerprint names image " + std::to_string(image) + " but the reference has " +
                  std::to_string(stack.numImages()) + " images");
    stack.imageLinear(image, buffer.data());
    std::array<double, 3> sum{0, 0, 0};
    for (std::size_t i = 0; i < buffer.size(); ++i) sum[i % 3] += buffer[i];
    for (double& v : sum) v /= std::max(1, stack.numTexels());
    m.means.push_back(sum);
    for (std::size_t t = 0; t < texels.size(); ++t) {
      const float* rgb = buffer.data() + 3 * static_cast<std::size_t>(texels[t]);
      values[t].push_back(0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]);
    }
  }
  m.pattern.assign(texels.size(), 0.0);
  for (std::size_t t = 0; t < texels.size(); ++t) {
    std::vector<double>& v = values[t];
    if (v.empty()) continue;
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    m.pattern[t] = v[v.size() / 2];
  }
  return m;
}

}  // namespace

SourceFingerprint sourceFingerprint(const BtfStack& stack, int maxImages) {
  SourceFingerprint fp;
  const int n = stack.numImages(), count = std::min(n, std::max(1, maxImages));
  for (int i = 0; i < count; ++i) fp.images.push_back(static_cast<int>(static_cast<long long>(i) * n / count));
  Measured measured = measure(stack, fp.images, patternTexels(stack.width(), stack.height(), fp.gridX, fp.gridY));
  fp.meanRgb = std::move(measured.means);
  const std::vector<double>& lum = measured.pattern;
  fp.patternMin = *std::min_element(lum.begin(), lum.end());
  fp.patternMax = *std::max_element(lum.begin(), lum.end());
  const double range = fp.patternMax - fp.patternMin;
  for (double v : lum)
    fp.pattern.push_back(range > 0 ? static_cast<std::uint8_t>(std::lround(255 * (v - fp.patternMin) / range)) : 0);
  return fp;
}

std::string sourceFingerprintJson(const SourceFingerprint& fp) {
  json j;
  j["what"] = "mean linear RGB over the texels of evenly spaced images";
  j["images"] = fp.images;
  json means = json::array();
  for (const auto& m : fp.meanRgb) means.push_back({m[0], m[1], m[2]});
  j["mean_linear_rgb"] = means;
  if (!fp.pattern.empty())
    j["texel_pattern"] = {{"what", "median linear luminance over those images at a grid of texels, 8 bits from min to max"},
                          {"grid", {fp.gridX, fp.gridY}},
                          {"min", fp.patternMin},
                          {"max", fp.patternMax},
                          {"hex", toHex(fp.pattern.data(), fp.pattern.size())}};
  return j.dump();
}

std::optional<SourceFingerprint> sourceFingerprintOf(const std::string& metadataJson, const std::string& fileName) {
  json meta = json::parse(metadataJson, nullptr, /*allow_exceptions=*/false);
  if (!meta.is_object() || !meta.contains("source") || !meta["source"].is_object() ||
      !meta["source"].contains("fingerprint"))
    return std::nullopt;
  const json& j = meta["source"]["fingerprint"];
  auto bad = [&](const std::string& what) -> Error {
    return fileError(fileName, "malformed source fingerprint in the metadata: " + what);
  };
  if (!j.is_object() || !j.contains("images") || !j.contains("mean_linear_rgb") || !j["images"].is_array() ||
      !j["mean_linear_rgb"].is_array() || j["images"].size() != j["mean_linear_rgb"].size())
    throw bad("expected \"images\" and \"mean_linear_rgb\" arrays of one length");
  SourceFingerprint fp;
  for (std::size_t i = 0; i < j["images"].size(); ++i) {
    const json& idx = j["images"][i];
    const json& rgb = j["mean_linear_rgb"][i];
    if (!idx.is_number_integer() || idx.get<long long>() < 0 || idx.get<long long>() > (1 << 30))
      throw bad("image index " + std::to_string(i) + " is not a non-negative integer");
    if (!rgb.is_array() || rgb.size() != 3) throw bad("entry " + std::to_string(i) + " is not an RGB triple");
    std::array<double, 3> m{};
    for (int c = 0; c < 3; ++c) {
      if (!rgb[c].is_number() || !std::isfinite(rgb[c].get<double>())) throw bad("a mean is not a finite number");
      m[c] = rgb[c].get<double>();
    }
    fp.images.push_back(idx.get<int>());
    fp.meanRgb.push_back(m);
  }
  if (j.contains("texel_pattern")) {
    const json& p = j["texel_pattern"];
    if (!p.is_object() || !p.contains("grid") || !p["grid"].is_array() || p["grid"].size() != 2 ||
        !p["grid"][0].is_number_integer() || !p["grid"][1].is_number_integer() || !p.contains("min") ||
        !p["min"].is_number() || !p.contains("max") || !p["max"].is_number() || !p.contains("hex") ||
        !p["hex"].is_string())
      throw bad("\"texel_pattern\" needs \"grid\" [x, y], \"min\", \"max\" and \"hex\"");
    fp.gridX = p["grid"][0].get<int>(), fp.gridY = p["grid"][1].get<int>();
    fp.patternMin = p["min"].get<double>(), fp.patternMax = p["max"].get<double>();
    const std::string hex = p["hex"].get<std::string>();
    if (fp.gridX < 1 || fp.gridY < 1 || fp.gridX > 1024 || fp.gridY > 1024 ||
        hex.size() != 2 * static_cast<std::size_t>(fp.gridX) * fp.gridY || !std::isfinite(fp.patternMin) ||
        !std::isfinite(fp.patternMax) || fp.patternMax < fp.patternMin)
      throw bad("\"texel_pattern\" is inconsistent (grid, hex length or range)");
    if (!fromHex(hex, fp.pattern)) throw bad("\"texel_pattern\" is not hex");
  }
  return fp;
}

FingerprintCheck checkSourceFingerprint(const SourceFingerprint& stored, const BtfStack& reference, double tolerance,
                                        double patternTolerance) {
  FingerprintCheck check;
  double brightest = 0;
  for (const auto& m : stored.meanRgb) brightest = std::max({brightest, m[0], m[1], m[2]});
  const double floor = 0.01 * brightest + 1e-12;
  std::vector<double> diffs;
  double worst = -1;
  int gx = 0, gy = 0;
  const std::vector<int> texels = patternTexels(reference.width(), reference.height(), gx, gy);
  const Measured measuredRef = measure(reference, stored.images, texels);
  for (std::size_t i = 0; i < stored.images.size(); ++i) {
    const int image = stored.images[i];
    const std::array<double, 3>& measured = measuredRef.means[i];
    double imageWorst = 0;
    for (int c = 0; c < 3; ++c) {
      const double a = stored.meanRgb[i][c], b = measured[c];
      const double d = std::abs(a - b) / (std::max(a, b) + floor);
      diffs.push_back(d);
      imageWorst = std::max(imageWorst, d);
    }
    if (imageWorst > worst) {
      worst = imageWorst;
      check.worstImage = image;
      check.stored = stored.meanRgb[i];
      check.measured = measured;
    }
  }
  if (diffs.empty()) return check;
  std::nth_element(diffs.begin(), diffs.begin() + diffs.size() / 2, diffs.end());
  check.medianDifference = diffs[diffs.size() / 2];
  check.matches = check.medianDifference <= tolerance;

  // The texel pattern, where the file has one, the reference has the size it was sampled at
  // and the material has a pattern at all (a spread of at least 1% of its brightest mean).
  const double range = stored.patternMax - stored.patternMin;
  if (!stored.pattern.empty() && gx == stored.gridX && gy == stored.gridY && range > 0.01 * brightest) {
    const std::vector<double>& lum = measuredRef.pattern;
    std::vector<double> a(lum.size());
    double mean = 0;
    for (std::size_t t = 0; t < a.size(); ++t) mean += a[t] = stored.patternMin + range * stored.pattern[t] / 255.0;
    mean /= static_cast<double>(a.size());
    double variance = 0, sse = 0;
    for (std::size_t t = 0; t < a.size(); ++t) variance += (a[t] - mean) * (a[t] - mean), sse += (a[t] - lum[t]) * (a[t] - lum[t]);
    if (variance > 0) {
      check.patternDifference = std::sqrt(sse / variance);
      check.patternMatches = check.patternDifference <= patternTolerance;
      check.matches = check.matches && check.patternMatches;
    }
  }
  return check;
}

}  // namespace nbtf
