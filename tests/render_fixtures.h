// Shared fixtures for the renderer tests: simple material sources and a plain-ray oracle.
#pragma once
#include <cmath>
#include <string>

#include "render/integrator.h"
#include "render/material_source.h"
#include "render/scene.h"

namespace nbtf::testing {

// The same RGB everywhere, for every direction.
class ConstantMaterial : public MaterialSource {
 public:
  explicit ConstantMaterial(float value = 0.5f, int w = 8, int h = 8) : value_(value), w_(w), h_(h) {}
  int width() const override { return w_; }
  int height() const override { return h_; }
  std::string name() const override { return "constant"; }
  void evaluate(const UvQuery*, std::size_t count, float* rgb) const override {
    for (std::size_t i = 0; i < 3 * count; ++i) rgb[i] = value_;
  }

 private:
  float value_;
  int w_, h_;
};

// A checkerboard of size x size texels: dark and bright texels, direction independent.
class CheckerMaterial : public MaterialSource {
 public:
  explicit CheckerMaterial(int size = 2, float dark = 0.1f, float bright = 0.9f) : n_(size), dark_(dark), bright_(bright) {}
  int width() const override { return n_; }
  int height() const override { return n_; }
  std::string name() const override { return "checker"; }
  int texel(double u, double v) const { return wrapTexel(v, n_) * n_ + wrapTexel(u, n_); }
  float valueOf(double u, double v) const {
    return ((wrapTexel(u, n_) + wrapTexel(v, n_)) % 2) ? bright_ : dark_;
  }
  void evaluate(const UvQuery* q, std::size_t count, float* rgb) const override {
    for (std::size_t i = 0; i < count; ++i) rgb[3 * i] = rgb[3 * i + 1] = rgb[3 * i + 2] = valueOf(q[i].u, q[i].v);
  }

 private:
  int n_;
  float dark_, bright_;
};

// Plain-ray oracle: the nearest shape hit by the camera ray through (px, py), -1 for none.
inline int nearestShape(const Scene& scene, const Camera& camera, double px, double py, SurfaceHit<double>* out = nullptr) {
  const Ray<double> ray = camera.ray<double>(px, py);
  int best = -1;
  double bestT = 1e300;
  for (std::size_t i = 0; i < scene.shapes.size(); ++i) {
    SurfaceHit<double> h;
    if (intersectShape<double>(scene.shapes[i], ray, 1e-6, 1e300, &h) && h.t < bestT) {
      best = static_cast<int>(i), bestT = h.t;
      if (out) *out = h;
    }
  }
  return best;
}

// Whether the sun reaches the point seen through (px, py) (false off the objects).
inline bool directlyLit(const Scene& scene, const Camera& camera, double px, double py) {
  SurfaceHit<double> h;
  const Ray<double> ray = camera.ray<double>(px, py);
  if (nearestShape(scene, camera, px, py, &h) < 0) return false;
  Vec3d n = h.n;
  if (dot(ray.dir, n) > 0) n = -n;
  if (dot(n, scene.toLight) <= 0) return false;
  const Ray<double> shadow{h.p + n * 1e-4, scene.toLight};
  for (const Shape& s : scene.shapes)
    if (intersectShape<double>(s, shadow, 1e-4, 1e300, nullptr)) return false;
  return true;
}

}  // namespace nbtf::testing
