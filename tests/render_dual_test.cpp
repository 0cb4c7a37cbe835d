// Dual numbers against finite differences: the arithmetic, the camera, every intersection
// routine (t, point, normal) and the texture coordinates.
#include <gtest/gtest.h>

#include <cmath>

#include "render/camera.h"
#include "render/dual.h"
#include "render/scene.h"
#include "render/shapes.h"
#include "render_fixtures.h"

namespace nbtf {
namespace {

// Central difference of f at (x, y) along x (axis 0) or y (axis 1).
template <class F>
double centralDiff(const F& f, double x, double y, int axis, double h = 1e-5) {
  return axis == 0 ? (f(x + h, y) - f(x - h, y)) / (2 * h) : (f(x, y + h) - f(x, y - h)) / (2 * h);
}

void expectDerivatives(const Dual& d, double fdx, double fdy, double tol, const std::string& what) {
  EXPECT_NEAR(d.dx, fdx, tol * (1 + std::fabs(fdx))) << what << " d/dx";
  EXPECT_NEAR(d.dy, fdy, tol * (1 + std::fabs(fdy))) << what << " d/dy";
}

TEST(RenderDual, ArithmeticMatchesFiniteDifferences) {
  auto f = [](auto x, auto y) {
    using std::abs;
    using std::acos;
    using std::atan2;
    using std::cos;
    using std::exp;
    using std::sin;
    using std::sqrt;
    return sqrt(x * x + y * 3.0 + 1.0) / (2.0 + sin(x * y)) + exp(-x * 0.3) * cos(y) + atan2(y, x) +
           acos(x * 0.1 + y * 0.05) - abs(x - y * 2.0);
  };
  for (auto [x, y] : {std::pair{0.7, 1.3}, std::pair{-1.2, 0.4}, std::pair{2.5, -0.8}}) {
    const Dual d = f(Dual(x, 1, 0), Dual(y, 0, 1));
    EXPECT_DOUBLE_EQ(d.v, f(x, y));
    auto plain = [&](double a, double b) { return f(a, b); };
    expectDerivatives(d, centralDiff(plain, x, y, 0), centralDiff(plain, x, y, 1), 1e-6, "f");
  }
}

TEST(RenderDual, MayCrossUsesTheFootprintCorners) {
  const Dual a(1.0, 0.6, -0.6);  // corners reach 1 +- 0.6 with half = 0.5
  EXPECT_TRUE(mayCross(a, 0.5, 0.5));
  EXPECT_FALSE(mayCross(a, 0.3, 0.5));
  EXPECT_FALSE(mayCross(a, 0.5, 0.1));
  EXPECT_DOUBLE_EQ(extrapolate(a, 0.5, -0.5), 1.6);
}

TEST(RenderDual, CameraRayDerivatives) {
  const Camera cam({{0.3, 2, 4}, {0, 0.5, 0}, 40}, 64, 48);
  const Ray<Dual> r = cam.dualRay(20.5, 30.5);
  for (int c = 0; c < 3; ++c) {
    auto comp = [&](double x, double y) {
      const Ray<double> p = cam.ray<double>(x, y);
      return c == 0 ? p.dir.x : c == 1 ? p.dir.y : p.dir.z;
    };
    const Dual& d = c == 0 ? r.dir.x : c == 1 ? r.dir.y : r.dir.z;
    expectDerivatives(d, centralDiff(comp, 20.5, 30.5, 0), centralDiff(comp, 20.5, 30.5, 1), 1e-6, "ray dir");
  }
}

// For every pixel of a coarse grid whose ray hits `shape` away from any edge, the Dual hit's
// derivatives (t, point, normal, u, v) match central differences of plain intersections.
int checkShape(const Shape& shape, const CameraSpec& spec) {
  const int W = 64, H = 48;
  const Camera cam(spec, W, H);
  int checked = 0;
  for (int j = 2; j < H; j += 4)
    for (int i = 2; i < W; i += 4) {
      const double px = i + 0.5, py = j + 0.5;
      SurfaceHit<Dual> hd;
      EdgeProbe probe;
      probe.half = 0.5;
      if (!intersectShape(shape, cam.dualRay(px, py), 1e-6, 1e300, &hd, &probe) || probe.edge) continue;
      const double h = 1e-4;
      SurfaceHit<double> hs[4];
      bool all = true;
      const double ox[4] = {h, -h, 0, 0}, oy[4] = {0, 0, h, -h};
      for (int k = 0; k < 4; ++k) all &= intersectShape<double>(shape, cam.ray<double>(px + ox[k], py + oy[k]), 1e-6, 1e300, &hs[k]);
      if (!all) continue;
      // u wraps on the sphere and cylinder: differences across the seam are skipped.
      if (std::fabs(hs[0].u - hs[1].u) > 0.25 || std::fabs(hs[2].u - hs[3].u) > 0.25) continue;
      auto fd = [&](auto get, int axis) { return axis == 0 ? (get(hs[0]) - get(hs[1])) / (2 * h) : (get(hs[2]) - get(hs[3])) / (2 * h); };
      auto check = [&](const Dual& d, auto get, const char* what) {
        const double fx = fd(get, 0), fy = fd(get, 1);
        const double tol = 2e-4 * (1 + std::fabs(fx) + std::fabs(fy));
        EXPECT_NEAR(d.dx, fx, tol) << what << " at pixel " << i << "," << j;
        EXPECT_NEAR(d.dy, fy, tol) << what << " at pixel " << i << "," << j;
      };
      check(hd.t, [](const SurfaceHit<double>& s) { return s.t; }, "t");
      check(hd.p.x, [](const SurfaceHit<double>& s) { return s.p.x; }, "p.x");
      check(hd.p.y, [](const SurfaceHit<double>& s) { return s.p.y; }, "p.y");
      check(hd.p.z, [](const SurfaceHit<double>& s) { return s.p.z; }, "p.z");
      check(hd.n.x, [](const SurfaceHit<double>& s) { return s.n.x; }, "n.x");
      check(hd.n.y, [](const SurfaceHit<double>& s) { return s.n.y; }, "n.y");
      check(hd.u, [](const SurfaceHit<double>& s) { return s.u; }, "u");
      check(hd.v, [](const SurfaceHit<double>& s) { return s.v; }, "v");
      EXPECT_NEAR(hd.t.v, hs[0].t, 1e-3);  // the same surface
      ++checked;
    }
  return checked;
}

TEST(RenderDual, SphereIntersectionDerivatives) {
  const Scene s = makeScene("sphere", 2);
  EXPECT_GT(checkShape(s.shapes[0], s.camera), 30);
}

TEST(RenderDual, RectIntersectionDerivatives) {
  const Scene s = makeScene("plane", 3);
  EXPECT_GT(checkShape(s.shapes[0], s.camera), 30);
}

TEST(RenderDual, CylinderIntersectionDerivatives) {
  const Scene s = makeScene("cylinder", 2);
  EXPECT_GT(checkShape(s.shapes[0], s.camera), 20);
  // Also from below the rim, where the inside (the far root) shows.
  EXPECT_GT(checkShape(s.shapes[0], {{0, 4.5, 1.0}, {0, 0.5, 0}, 30}), 20);
}

TEST(RenderDual, ClothIntersectionDerivatives) {
  const Scene s = makeScene("cloth", 2);
  EXPECT_GT(checkShape(s.shapes[0], s.camera), 30);
}

TEST(RenderDual, ClothHeightFieldSlopes) {
  for (auto [x, z] : {std::pair{0.3, -0.2}, std::pair{-0.9, 0.7}, std::pair{1.1, 1.2}}) {
    double hx, hz;
    clothSlope(x, z, hx, hz);
    const double e = 1e-6;
    EXPECT_NEAR(hx, (clothHeight(x + e, z) - clothHeight(x - e, z)) / (2 * e), 1e-6);
    EXPECT_NEAR(hz, (clothHeight(x, z + e) - clothHeight(x, z - e)) / (2 * e), 1e-6);
  }
}

}  // namespace
}  // namespace nbtf
