// Learned feature planes over direction space: three R x R grids of F features each, over the
// stereographic disk of the light, of the view and of the half vector. The decoder's input
// gets, after the fixed direction inputs, each plane's bilinear interpolation at the pair's
// point (3 F values). A grid cell is a free parameter that only nearby directions touch, so the
// planes learn sharp angular features (highlights, shadowing edges) in far fewer steps than
// the network's own layers do (the lesson of grid encodings; Neural Biplane, Fan et al. 2023,
// puts such a plane over the half vector). Shared by training (model/) and the decoder (codec/),
// so both compute the same values bit for bit.
#pragma once
#include <array>
#include <cstddef>
#include <vector>

#include "util/directions.h"

namespace nbtf {

struct DirectionPlanes {
  static constexpr int kPlanes = 3;        // light, view, half vector
  static constexpr int kMaxResolution = 64;
  static constexpr int kMaxFeatures = 8;
  int resolution = 0;                      // R: grid points per side, over [-1, 1] (corners included)
  int features = 0;                        // F per plane; 0 = no planes
  std::vector<float> values;               // [plane][y][x][feature], kPlanes x R x R x F

  bool empty() const { return features == 0; }
  int inputCount() const { return kPlanes * features; }  // decoder inputs they add
  std::size_t valueCount() const {
    return static_cast<std::size_t>(kPlanes) * resolution * resolution * features;
  }
};

// Direction planes of each latent row's own ("cluster planes"): every cluster (or texel, in
// the per-texel mode) has three R x R grids of F features over the same disks as
// DirectionPlanes, appended to the decoder's direction inputs after the shared planes. They
// give each cluster's angular function free parameters of its own, so the network no longer
// has to carry every cluster's highlights and shadows in its weights.
struct RowPlanes {
  int resolution = 0;                      // R
  int features = 0;                        // F per plane; 0 = none
  int rows = 0;                            // latent rows
  std::vector<float> values;               // [row][plane][y][x][feature]

  bool empty() const { return features == 0; }
  int inputCount() const { return DirectionPlanes::kPlanes * features; }
  std::size_t valuesPerRow() const {
    return static_cast<std::size_t>(DirectionPlanes::kPlanes) * resolution * resolution * features;
  }
  std::size_t valueCount() const { return static_cast<std::size_t>(rows) * valuesPerRow(); }
  const float* rowValues(int row) const { return values.data() + static_cast<std::size_t>(row) * valuesPerRow(); }
};

// The most direction inputs a decoder takes: the widest fixed encoding and the most plane features.
constexpr int kMaxDecoderDirectionInputs =
    kMaxDirectionInputs + 2 * DirectionPlanes::kPlanes * DirectionPlanes::kMaxFeatures;

// The points a (light, view) pair samples, in [-1, 1]^2 each: the stereographic projections
// (x / (1 + z), y / (1 + z); the horizon maps to radius 1) of the unit light, view and half
// vector h = (l + v) / |l + v| (the normal when l = -v). out: 6 floats.
void directionPlanePoints(const std::array<double, 3>& light, const std::array<double, 3>& view, float* out);

// The planes' features at `points` (6 floats): out gets inputCount() floats, plane by plane.
// Points outside [-1, 1] are clamped to the border.
void sampleDirectionPlanes(const DirectionPlanes& planes, const float* points, float* out);

// The same on raw grids: `values` laid out as DirectionPlanes::values for resolution R, F features.
void sampleDirectionPlanes(int resolution, int features, const float* values, const float* points, float* out);
void scatterDirectionPlanesGradient(int resolution, int features, const float* points, const float* dOut,
                                    float* gradient);

// Where one pair's points fall on an R-point grid, for every plane: the cell's first corner
// (y0 x R + x0) and the bilinear weights of its corners (x0, y0), (x0 + 1, y0), (x0, y0 + 1),
// (x0 + 1, y0 + 1). Training samples the same pairs every step, so it computes these once.
struct PlaneTaps {
  int corner[DirectionPlanes::kPlanes];
  float weight[DirectionPlanes::kPlanes][4];
};
PlaneTaps planeTaps(int resolution, const float* points);

// sampleDirectionPlanes and scatterDirectionPlanesGradient from taps, the same arithmetic.
// The scatter adds features [firstFeature, endFeature) of every plane only, so that threads
// owning disjoint features can share one gradient and still add each value in row order.
void sampleDirectionPlanes(const PlaneTaps& taps, int resolution, int features, const float* values, float* out);
void scatterDirectionPlanesGradient(const PlaneTaps& taps, int resolution, int features, const float* dOut,
                                    float* gradient, int firstFeature, int endFeature);

// The transpose of sampleDirectionPlanes: adds the gradient dOut (inputCount() floats) of
// the sampled features at `points` to gradient (valueCount() floats, laid out as values).
void scatterDirectionPlanesGradient(const DirectionPlanes& planes, const float* points, const float* dOut,
                                    float* gradient);

}  // namespace nbtf
