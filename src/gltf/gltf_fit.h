// Fitting the glTF metallic-roughness material to a BTF, texel by texel: base colour,
// metallic, roughness and a shading normal (the meso-structure a BRDF alone cannot hold goes
// into the normal map) by Levenberg-Marquardt on the squared error of the values (linear
// RGB), in the radiometric convention of gltf_material.h.
//
// The fit sees a fixed subset of the (light, view) images (the same for every texel, drawn
// with the seed). A lobe narrower than the spacing of those images can put a peak where none
// of them looked, many times brighter than the material: so a fit may not predict, at any
// measured (light, view) pair (up to kPeakCheckPairs of them), more than kPeakMargin x the
// texel's largest value over all images (read once for this); one that does is fitted again with a higher roughness floor
// (kRoughnessFloors). The report measures the result on all images (gltf_report.h).
#pragma once
#include <cstdint>
#include <functional>
#include <vector>

#include "gltf/gltf_material.h"
#include "util/directions.h"

namespace nbtf::gltf {

struct FitOptions {
  int samples = 512;        // (light, view) images the fit uses (all of them when there are fewer)
  int iterations = 50;      // most Levenberg-Marquardt steps per texel after the starts (converged ones stop)
  std::uint64_t seed = 1;
  double maxTiltDeg = 60;   // the shading normal's largest angle from the macro normal
  double minRoughness = 0.1;  // the smallest roughness the fit may choose
  bool sheen = false;         // also fit KHR_materials_sheen's colour and roughness per texel
  bool specular = false;      // also fit the dielectric's F0 per texel (KHR_materials_specular)
  bool progress = true;
};
// Throws nbtf::Error naming the option for values out of range.
void checkFitOptions(const FitOptions& options);

// A material's images in linear RGB: image(i, rgb) writes width x height x 3 floats of
// image i = light * views + view.
using ImageSource = std::function<void(int image, float* rgb)>;

constexpr double kPeakMargin = 1.25;
constexpr int kPeakCheckPairs = 6561;
constexpr double kRoughnessFloors[] = {0.3, 0.5, 1.0};  // tried in turn while the peak is too bright

struct FitData {
  int width = 0, height = 0;
  std::vector<int> images;          // the images used, ascending
  // The measured pairs the peak check looks at: all of them, or kPeakCheckPairs drawn with the
  // seed where there are more (a UBO2014 file's 22,801).
  std::vector<Vec3> checkLights, checkViews;
  std::vector<float> texelMax;      // per texel, its largest value (any channel) over all images
  std::vector<Vec3> lights, views;  // their unit directions (BTF frame), one per image used
  std::vector<float> values;        // texel-major: (texel * images.size() + i) * 3 + channel
  std::size_t count() const { return images.size(); }
};
FitData gatherFitData(int width, int height, const std::vector<Direction>& lights, const std::vector<Direction>& views,
                      const ImageSource& source, const FitOptions& options);

// The sun strength the material is fitted for: pi (a Lambertian albedo rho measured as
// rho x cos(theta_l) gets base colour rho), raised so that the 99th percentile of the texels'
// Lambertian estimates stays at base colour 0.95 (a base colour cannot exceed 1).
double chooseExposure(const FitData& data);

struct FitSummary {
  double seconds = 0;
  double sampleRmse = 0;  // over the fitted samples, linear (not normalized)
  int texels = 0;
  int refitted = 0;  // texels fitted again with a higher roughness floor (their peak was too bright)
};
// Fits every texel (in parallel, deterministic for any thread count).
GltfMaterial fitMaterial(const FitData& data, double exposure, const FitOptions& options, FitSummary* summary = nullptr);

// One texel of `d` (exposed for the tests). `refitted`: whether a higher floor was needed.
TexelParams fitTexel(const FitData& d, std::size_t texel, double exposure, const FitOptions& options,
                     double* cost = nullptr, bool* refitted = nullptr);

}  // namespace nbtf::gltf
