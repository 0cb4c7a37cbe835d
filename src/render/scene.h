// The scenes `nbtf render` knows: a BTF-covered object (plane, sphere, cylinder or a draped
// cloth), a grey diffuse ground or occluder, one directional light with hard shadows and a
// constant environment term (also the background).
//
// Radiance at a BTF point (x, light l, view v, local frame from the surface tangents):
//   L = sun * visible(l) * BTF(x, l, v) + env * BTF(x, n, v)
// BTF values carry the light's cosine, as measured stacks do, so the sun term needs none;
// the environment term is the BTF lit from the normal (a one-sample stand-in for the
// constant sky). The grey material: L = albedo * (sun * visible * max(0, n.l) + env).
// The background is env.
#pragma once
#include <string>
#include <vector>

#include "util/directions.h"
#include "render/camera.h"
#include "render/shapes.h"

namespace nbtf {

struct Scene {
  std::string name;
  std::vector<Shape> shapes;
  Vec3d toLight{0, 1, 0};  // unit vector towards the light (world, +y up)
  double sun = 1.0, env = 0.25;
  double albedo = 0.5;     // the grey material
  CameraSpec camera;       // the scene's default view
};

// "plane", "tile" (the plane alone: what another renderer is compared on), "sphere", "cylinder", "cloth".
const std::vector<std::string>& sceneNames();
// Throws nbtf::Error naming the option and listing the known scenes for any other name.
Scene makeScene(const std::string& name, double tiling, const std::string& option = "--scene");
// World direction towards the light from (theta from +y, phi from +x towards +z), degrees.
Vec3d lightVector(const Direction& d);
void setLight(Scene& scene, const Direction& d);

}  // namespace nbtf
