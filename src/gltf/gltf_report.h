// How far a fitted glTF material is from a BTF: RMSE over every (light, view) image and texel,
// in linear RGB divided by the material's alpha (the global maximum of the stack's values: the
// paper's eq. 10 normalization, the one `nbtf eval` prints), overall and by the light's and the
// view's elevation (15-degree bands of theta: grazing angles are where an analytic BRDF fails
// first).
#pragma once
#include <string>
#include <vector>

#include "gltf/gltf_fit.h"
#include "util/layout.h"

namespace nbtf::gltf {

struct Reference {
  std::string name;    // "stack", "ground_truth", "nbtf"
  std::string source;  // its path
  ImageSource image;   // linear RGB, same size and directions as the fit
};

struct ElevationBand {
  double thetaFromDeg = 0, thetaToDeg = 0;
  double rmse = 0;     // linear / alpha
  std::size_t values = 0;
};
struct FitError {
  std::string name, source;
  double rmse = 0;  // linear / alpha
  std::vector<ElevationBand> byLight, byView;
};

// Every image of every reference against the material's values (views in the outer loop, so
// a source that reads a file per view reads each once). Deterministic.
std::vector<FitError> measureFitErrors(const GltfMaterial& m, const std::vector<Direction>& lights,
                                       const std::vector<Direction>& views, const std::vector<Reference>& references,
                                       double alpha, bool progress);

// The float ground truth beside a stack folder (nbtf-synth's, io/ground_truth.h) as an image
// source, cropped like the stack; each view's file is read once while images come view by view.
ImageSource groundTruthSource(const std::string& stackDir, const std::vector<Direction>& lights,
                              const std::vector<Direction>& views, const Crop& crop, int width, int height);

}  // namespace nbtf::gltf
