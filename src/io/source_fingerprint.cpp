#include "io/source_fingerprint.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "util/error.h"

namespace nbtf {
namespace {

using json = nlohmann::json;

std::array<double, 3> meanOfImage(const BtfStack& stack, int image, std::vector<float>& buffer) {
  buffer.resize(static_cast<std::size_t>(stack.numTexels()) * 3);
  stack.imageLinear(image, buffer.data());
  std::array<double, 3> sum{0, 0, 0};
  for (std::size_t i = 0; i < buffer.size(); ++i) sum[i % 3] += buffer[i];
  for (double& s : sum) s /= std::max(1, stack.numTexels());
  return sum;
}

}  // namespace

SourceFingerprint sourceFingerprint(const BtfStack& stack, int maxImages) {
  SourceFingerprint fp;
  const int n = stack.numImages(), count = std::min(n, std::max(1, maxImages));
  std::vector<float> buffer;
  for (int i = 0; i < count; ++i) {
    const int image = static_cast<int>(static_cast<long long>(i) * n / count);
    fp.images.push_back(image);
    fp.meanRgb.push_back(meanOfImage(stack, image, buffer));
  }
  return fp;
}

std::string sourceFingerprintJson(const SourceFingerprint& fp) {
  json j;
  j["what"] = "mean linear RGB over the texels of evenly spaced images";
  j["images"] = fp.images;
  json means = json::array();
  for (const auto& m : fp.meanRgb) means.push_back({m[0], m[1], m[2]});
  j["mean_linear_rgb"] = means;
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
  return fp;
}

FingerprintCheck checkSourceFingerprint(const SourceFingerprint& stored, const BtfStack& reference, double tolerance) {
  FingerprintCheck check;
  double brightest = 0;
  for (const auto& m : stored.meanRgb) brightest = std::max({brightest, m[0], m[1], m[2]});
  const double floor = 0.01 * brightest + 1e-12;
  std::vector<double> diffs;
  std::vector<float> buffer;
  double worst = -1;
  for (std::size_t i = 0; i < stored.images.size(); ++i) {
    const int image = stored.images[i];
    if (image >= reference.numImages())
      throw Error("the source fingerprint names image " + std::to_string(image) + " but the reference has " +
                  std::to_string(reference.numImages()) + " images");
    const std::array<double, 3> measured = meanOfImage(reference, image, buffer);
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
  return check;
}

}  // namespace nbtf
