// Error metrics of the evaluation report.
//
// The paper's RMSE, eq. (10), is taken over every value of the BTF (texels x images x RGB
// channels) on linear values divided by alpha, the global maximum of the reference, so
// that targets lie in [0, 1]. We also report the RMSE in 8-bit sRGB code units (both
// sides encoded with the sRGB transfer curve, clamped to [0, 1], rounded to 0..255: the
// units of the JPEG/PNG source images) and the PSNR of each (peak 1 in alpha-normalized
// linear space, peak 255 in sRGB 8-bit codes).
//
// Errors are accumulated per image (light, view) as sums of squares in double, so every
// grouping the report shows (all images, training / held-out, per light or view
// elevation, the 81 x 81 map) is the RMSE of exactly the values of that group, pooled as
// sqrt(sum of squares / count) - never an average of RMSEs.
#pragma once
#include <cstddef>
#include <cstdint>
#include <vector>

#include "util/directions.h"

namespace nbtf {

// Squared-error sums of one group of values.
struct ErrorSums {
  double squaredLinear = 0;  // sum of (ref/alpha - rec/alpha)^2
  double squaredSrgb8 = 0;   // sum of (sRGB8(ref) - sRGB8(rec))^2, code units
  std::uint64_t count = 0;   // values (texels x channels x images)

  ErrorSums& operator+=(const ErrorSums& o) {
    squaredLinear += o.squaredLinear, squaredSrgb8 += o.squaredSrgb8, count += o.count;
    return *this;
  }
};

// The metrics of one group. PSNR is +infinity when the RMSE is exactly 0.
struct ErrorSummary {
  double rmse = 0;        // linear, alpha-normalized (eq. 10)
  double rmseSrgb8 = 0;   // sRGB 8-bit code units (0..255)
  double psnr = 0;        // dB, peak 1 (linear, alpha-normalized)
  double psnrSrgb8 = 0;   // dB, peak 255 (sRGB 8-bit)
  std::uint64_t count = 0;
};

// PSNR = 20 log10(peak / rmse); +infinity for rmse == 0.
double psnrFromRmse(double rmse, double peak);
ErrorSummary summarize(const ErrorSums& sums);

// Sums over n values (n = texels x 3), linear RGB, not normalized. Throws nbtf::Error naming
// the value index if either side holds a NaN or infinity (never a silent NaN), or if
// alpha is not positive.
ErrorSums errorSums(const float* reference, const float* reconstruction, std::size_t n, float alpha);

// Direct forms for one buffer (used by the blur estimator and tests).
double rmseLinear(const float* reference, const float* reconstruction, std::size_t n, float alpha);
double rmseSrgb8(const float* reference, const float* reconstruction, std::size_t n);

// RMSE of one elevation ring: all images whose light (or view) has this theta.
struct ElevationError {
  double thetaDeg = 0;
  int directions = 0;  // light (or view) directions on the ring
  int images = 0;      // images pooled
  ErrorSummary error;
};

// Per-image error sums of a whole stack, indexed image = light * numViews + view.
class ErrorTable {
 public:
  ErrorTable() = default;
  ErrorTable(std::vector<Direction> lights, std::vector<Direction> views);

  int numLights() const { return static_cast<int>(lights_.size()); }
  int numViews() const { return static_cast<int>(views_.size()); }
  int numImages() const { return numLights() * numViews(); }
  const std::vector<Direction>& lights() const { return lights_; }
  const std::vector<Direction>& views() const { return views_; }

  // Stores one image's sums (distinct images may be set from different threads).
  void set(int image, const ErrorSums& sums);
  const ErrorSums& sums(int image) const { return images_.at(static_cast<std::size_t>(image)); }
  ErrorSummary image(int image) const { return summarize(sums(image)); }

  ErrorSummary all() const;
  // Images in `selected` (ascending or not; duplicates rejected) or all the others.
  ErrorSummary subset(const std::vector<int>& selected, bool complement) const;
  // Rings by light / view elevation, theta ascending. Thetas are grouped by their value
  // rounded to whole degrees (UTIA shifts a few light angles slightly off the grid).
  std::vector<ElevationError> byLightElevation() const;
  std::vector<ElevationError> byViewElevation() const;
  // The image with the largest RMSE (linear, alpha-normalized); the first on ties.
  int worstImage() const;
  // RMSE (linear, alpha-normalized) of every image, light-major: numLights x numViews.
  std::vector<double> rmseMap() const;

 private:
  std::vector<ElevationError> byElevation(bool light) const;
  std::vector<Direction> lights_, views_;
  std::vector<ErrorSums> images_;
};

// Validates a hold-out list against the image count: indices in range, no duplicates.
// Throws nbtf::Error naming the first bad entry.
void checkHoldoutImages(const std::vector<int>& holdout, int numImages);

}  // namespace nbtf
