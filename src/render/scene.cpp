#include "render/scene.h"

#include <cmath>

#include "util/error.h"

namespace nbtf {

const std::vector<std::string>& sceneNames() {
  static const std::vector<std::string> names = {"plane", "tile", "sphere", "cylinder", "cloth"};
  return names;
}

Vec3d lightVector(const Direction& d) {
  const double t = d.thetaDeg * M_PI / 180, p = d.phiDeg * M_PI / 180;
  return {std::sin(t) * std::cos(p), std::cos(t), std::sin(t) * std::sin(p)};
}

void setLight(Scene& scene, const Direction& d) {
  checkHemisphere(d, "--light");
  scene.toLight = normalize(lightVector(d));
}

namespace {
Shape ground(double half) {
  Shape g;
  g.kind = ShapeKind::Rect;
  g.material = 1;
  g.center = {0, 0, 0};
  g.e1 = {1, 0, 0};
  g.e2 = {0, 0, -1};  // normal e1 x e2 = +y
  g.a1 = g.a2 = half;
  return g;
}
}  // namespace

Scene makeScene(const std::string& name, double tiling, const std::string& option) {
  if (!(tiling > 0) || !std::isfinite(tiling)) throw Error("--tiling must be a positive number");
  Scene s;
  s.name = name;
  setLight(s, {45, 300});
  if (name == "plane" || name == "tile") {
    Shape p;
    p.kind = ShapeKind::Rect;
    p.center = {0, 0, 0};
    p.e1 = {1, 0, 0};
    p.e2 = {0, 0, -1};
    p.a1 = p.a2 = 1;
    p.tiling = tiling;
    s.shapes = {p};
    if (name == "plane") {
      Shape occluder;  // a grey ball above the sample, casting a shadow onto it
      occluder.kind = ShapeKind::Sphere;
      occluder.material = 1;
      occluder.center = {-0.25, 0.45, 0.25};
      occluder.radius = 0.22;
      s.shapes.push_back(occluder);
    }
    s.camera = {{0, 2.3, 2.4}, {0, 0, 0.1}, 45};
  } else if (name == "sphere") {
    Shape b;
    b.kind = ShapeKind::Sphere;
    b.center = {0, 1, 0};
    b.radius = 1;
    b.tiling = tiling;
    s.shapes = {b, ground(8)};
    s.camera = {{0, 2.2, 4.2}, {0, 0.85, 0}, 38};
  } else if (name == "cylinder") {
    Shape c;
    c.kind = ShapeKind::Cylinder;
    c.center = {0, 0, 0};
    c.radius = 0.7;
    c.y0 = 0, c.y1 = 1.6;
    c.tiling = tiling;
    s.shapes = {c, ground(8)};
    s.camera = {{0, 3.2, 4.0}, {0, 0.55, 0}, 42};
  } else if (name == "cloth") {
    Shape c;
    c.kind = ShapeKind::Cloth;
    c.a1 = c.a2 = 1.3;
    c.tiling = tiling;
    s.shapes = {c, ground(8)};
    s.camera = {{0, 2.9, 4.1}, {0, 0.2, 0}, 42};
  } else {
    std::string known;
    for (const auto& n : sceneNames()) known += (known.empty() ? "" : ", ") + n;
    throw Error(option + ": unknown scene '" + name + "' (known: " + known + ")");
  }
  return s;
}

}  // namespace nbtf
