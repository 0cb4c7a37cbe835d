#include "util/direction_planes.h"

#include <algorithm>
#include <cmath>

namespace nbtf {
namespace {

// Bilinear taps of point (x, y) on an R x R grid over [-1, 1]^2 (grid point i at
// -1 + 2 i / (R - 1)): the cell's first corner and the weights along x and y.
struct Taps {
  int x0, y0;
  float fx, fy;
};

Taps tapsOf(int resolution, float x, float y) {
  const float scale = 0.5f * static_cast<float>(resolution - 1);
  auto axis = [&](float c, int& cell, float& frac) {
    const float g = std::min(std::max((c + 1.0f) * scale, 0.0f), static_cast<float>(resolution - 1));
    cell = std::min(static_cast<int>(g), resolution - 2);  // the last point is the far corner of the last cell
    frac = g - static_cast<float>(cell);
  };
  Taps t{};
  axis(x, t.x0, t.fx);
  axis(y, t.y0, t.fy);
  return t;
}

void stereographicPoint(double x, double y, double z, float* out) {
  out[0] = static_cast<float>(x / (1 + z));
  out[1] = static_cast<float>(y / (1 + z));
}

}  // namespace

void directionPlanePoints(const std::array<double, 3>& light, const std::array<double, 3>& view, float* out) {
  stereographicPoint(light[0], light[1], light[2], out);
  stereographicPoint(view[0], view[1], view[2], out + 2);
  double h[3] = {light[0] + view[0], light[1] + view[1], light[2] + view[2]};
  const double n = std::sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
  if (n > 1e-12) stereographicPoint(h[0] / n, h[1] / n, h[2] / n, out + 4);
  else out[4] = out[5] = 0;
}

void sampleDirectionPlanes(const DirectionPlanes& planes, const float* points, float* out) {
  sampleDirectionPlanes(planes.resolution, planes.features, planes.values.data(), points, out);
}

void scatterDirectionPlanesGradient(const DirectionPlanes& planes, const float* points, const float* dOut,
                                    float* gradient) {
  scatterDirectionPlanesGradient(planes.resolution, planes.features, points, dOut, gradient);
}

PlaneTaps planeTaps(int R, const float* points) {
  PlaneTaps taps{};
  for (int p = 0; p < DirectionPlanes::kPlanes; ++p) {
    const Taps t = tapsOf(R, points[2 * p], points[2 * p + 1]);
    taps.corner[p] = t.y0 * R + t.x0;
    float* w = taps.weight[p];
    w[0] = (1 - t.fx) * (1 - t.fy), w[1] = t.fx * (1 - t.fy), w[2] = (1 - t.fx) * t.fy, w[3] = t.fx * t.fy;
  }
  return taps;
}

void sampleDirectionPlanes(const PlaneTaps& taps, int R, int F, const float* values, float* out) {
  const std::size_t planeSize = static_cast<std::size_t>(R) * R * F;
  for (int p = 0; p < DirectionPlanes::kPlanes; ++p) {
    const float* v00 = values + p * planeSize + static_cast<std::size_t>(taps.corner[p]) * F;
    const float* v01 = v00 + F;                                  // x + 1
    const float* v10 = v00 + static_cast<std::size_t>(R) * F;    // y + 1
    const float* v11 = v10 + F;
    const float* w = taps.weight[p];
    for (int f = 0; f < F; ++f) out[p * F + f] = w[0] * v00[f] + w[1] * v01[f] + w[2] * v10[f] + w[3] * v11[f];
  }
}

void scatterDirectionPlanesGradient(const PlaneTaps& taps, int R, int F, const float* dOut, float* gradient,
                                    int firstFeature, int endFeature) {
  const std::size_t planeSize = static_cast<std::size_t>(R) * R * F;
  for (int p = 0; p < DirectionPlanes::kPlanes; ++p) {
    float* g00 = gradient + p * planeSize + static_cast<std::size_t>(taps.corner[p]) * F;
    float* g01 = g00 + F;
    float* g10 = g00 + static_cast<std::size_t>(R) * F;
    float* g11 = g10 + F;
    const float* w = taps.weight[p];
    const float* d = dOut + p * F;
    for (int f = firstFeature; f < endFeature; ++f) {
      g00[f] += w[0] * d[f];
      g01[f] += w[1] * d[f];
      g10[f] += w[2] * d[f];
      g11[f] += w[3] * d[f];
    }
  }
}

void sampleDirectionPlanes(int R, int F, const float* values, const float* points, float* out) {
  sampleDirectionPlanes(planeTaps(R, points), R, F, values, out);
}

void scatterDirectionPlanesGradient(int R, int F, const float* points, const float* dOut, float* gradient) {
  scatterDirectionPlanesGradient(planeTaps(R, points), R, F, dOut, gradient, 0, F);
}

}  // namespace nbtf
