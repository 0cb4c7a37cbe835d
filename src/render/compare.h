// Comparing two renders of the same scene (the paper's Tables 3-4): the RMSE of linear
// radiance over the whole image and over its darkest and brightest 10% (by the reference's
// luminance, among the pixels that show the material: coverage >= 0.5; the whole image when
// no pixel does), plus the images a user looks at.
#pragma once
#include <cstddef>
#include <string>
#include <vector>

#include "render/integrator.h"

namespace nbtf {

// sqrt(mean of squared differences) over n floats.
double rmseOf(const float* a, const float* b, std::size_t n);

struct RegionRmse {
  double rmse = 0;
  std::size_t pixels = 0;
};
struct RenderComparison {
  RegionRmse all, dark, bright;  // whole image; darkest / brightest 10% of the material's pixels
  double darkMaxLuminance = 0, brightMinLuminance = 0;  // the regions' luminance bounds (reference)
  double maxAbsError = 0;
};
// Both images width x height x RGB, linear; `coverage` per pixel (the reference's).
RenderComparison compareImages(const std::vector<float>& reference, const std::vector<float>& test,
                               const std::vector<float>& coverage, int width, int height, double fraction = 0.1);

// |reference - test| x magnify, as linear RGB (write it as sRGB for display).
std::vector<float> errorImage(const std::vector<float>& reference, const std::vector<float>& test, double magnify);

struct CompareReportInfo {
  std::string reference, compressed;  // material paths
  std::string scene;
  int width = 0, height = 0;
  std::string sampling;               // e.g. "adaptive, 2 levels"
  double magnify = 8;
  double referenceSeconds = 0, compressedSeconds = 0;
};
std::string compareMarkdown(const RenderComparison& c, const CompareReportInfo& info);
std::string compareJson(const RenderComparison& c, const CompareReportInfo& info);

}  // namespace nbtf
