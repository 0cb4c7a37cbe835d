#include "eval/metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <string>

#include "io/color.h"
#include "util/error.h"

namespace nbtf {

double psnrFromRmse(double rmse, double peak) {
  if (rmse <= 0) return std::numeric_limits<double>::infinity();
  return 20.0 * std::log10(peak / rmse);
}

ErrorSummary summarize(const ErrorSums& sums) {
  ErrorSummary s;
  s.count = sums.count;
  if (sums.count == 0) return s;
  double n = static_cast<double>(sums.count);
  s.rmse = std::sqrt(sums.squaredLinear / n);
  s.rmseSrgb8 = std::sqrt(sums.squaredSrgb8 / n);
  s.psnr = psnrFromRmse(s.rmse, 1.0);
  s.psnrSrgb8 = psnrFromRmse(s.rmseSrgb8, 255.0);
  return s;
}

ErrorSums errorSums(const float* reference, const float* reconstruction, std::size_t n, float alpha) {
  if (!(alpha > 0) || !std::isfinite(alpha))
    throw Error("error metrics: alpha must be a positive finite number, got " + std::to_string(alpha));
  const double inv = 1.0 / alpha;
  ErrorSums s;
  for (std::size_t i = 0; i < n; ++i) {
    float r = reference[i], c = reconstruction[i];
    if (!std::isfinite(r) || !std::isfinite(c))
      throw Error(std::string(!std::isfinite(c) ? "reconstruction" : "reference") + " value " + std::to_string(i) +
                  " (texel " + std::to_string(i / 3) + ", channel " + std::to_string(i % 3) + ") is not finite");
    double d = (static_cast<double>(r) - c) * inv;
    s.squaredLinear += d * d;
    double e = static_cast<double>(linearToSrgb8(r)) - linearToSrgb8(c);
    s.squaredSrgb8 += e * e;
  }
  s.count = n;
  return s;
}

double rmseLinear(const float* reference, const float* reconstruction, std::size_t n, float alpha) {
  return summarize(errorSums(reference, reconstruction, n, alpha)).rmse;
}

double rmseSrgb8(const float* reference, const float* reconstruction, std::size_t n) {
  return summarize(errorSums(reference, reconstruction, n, 1.0f)).rmseSrgb8;
}

// ---- ErrorTable

ErrorTable::ErrorTable(std::vector<Direction> lights, std::vector<Direction> views)
    : lights_(std::move(lights)), views_(std::move(views)), images_(lights_.size() * views_.size()) {}

void ErrorTable::set(int image, const ErrorSums& sums) { images_.at(static_cast<std::size_t>(image)) = sums; }

ErrorSummary ErrorTable::all() const {
  ErrorSums total;
  for (const auto& s : images_) total += s;
  return summarize(total);
}

ErrorSummary ErrorTable::subset(const std::vector<int>& selected, bool complement) const {
  checkHoldoutImages(selected, numImages());
  std::vector<char> in(images_.size(), 0);
  for (int i : selected) in[static_cast<std::size_t>(i)] = 1;
  ErrorSums total;
  for (std::size_t i = 0; i < images_.size(); ++i)
    if (static_cast<bool>(in[i]) != complement) total += images_[i];
  return summarize(total);
}

std::vector<ElevationError> ErrorTable::byElevation(bool light) const {
  const auto& dirs = light ? lights_ : views_;
  // Ring key: theta rounded to whole degrees.
  std::map<long, std::vector<int>> rings;
  for (std::size_t d = 0; d < dirs.size(); ++d) rings[std::lround(dirs[d].thetaDeg)].push_back(static_cast<int>(d));
  std::vector<ElevationError> out;
  for (const auto& [key, members] : rings) {
    ElevationError row;
    double thetaSum = 0;
    ErrorSums total;
    for (int d : members) {
      thetaSum += dirs[static_cast<std::size_t>(d)].thetaDeg;
      int others = light ? numViews() : numLights();
      for (int o = 0; o < others; ++o) {
        int image = light ? d * numViews() + o : o * numViews() + d;
        total += images_[static_cast<std::size_t>(image)];
        ++row.images;
      }
    }
    row.thetaDeg = thetaSum / members.size();
    row.directions = static_cast<int>(members.size());
    row.error = summarize(total);
    out.push_back(row);
  }
  return out;
}

std::vector<ElevationError> ErrorTable::byLightElevation() const { return byElevation(true); }
std::vector<ElevationError> ErrorTable::byViewElevation() const { return byElevation(false); }

int ErrorTable::worstImage() const {
  int worst = -1;
  double worstMse = -1;
  for (std::size_t i = 0; i < images_.size(); ++i) {
    const auto& s = images_[i];
    double mse = s.count ? s.squaredLinear / static_cast<double>(s.count) : 0;
    if (mse > worstMse) worstMse = mse, worst = static_cast<int>(i);
  }
  return worst;
}

std::vector<double> ErrorTable::rmseMap() const {
  std::vector<double> out(images_.size());
  for (std::size_t i = 0; i < images_.size(); ++i) out[i] = summarize(images_[i]).rmse;
  return out;
}

void checkHoldoutImages(const std::vector<int>& holdout, int numImages) {
  std::vector<char> seen(static_cast<std::size_t>(std::max(0, numImages)), 0);
  for (std::size_t k = 0; k < holdout.size(); ++k) {
    int i = holdout[k];
    if (i < 0 || i >= numImages)
      throw Error("hold-out image list: entry " + std::to_string(k) + " = " + std::to_string(i) +
                  " is outside 0.." + std::to_string(numImages - 1));
    if (seen[static_cast<std::size_t>(i)]++)
      throw Error("hold-out image list: image " + std::to_string(i) + " is listed twice");
  }
}

}  // namespace nbtf
