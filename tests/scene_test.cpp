// The built-in scenes (render/scene.cpp): their names and shapes, and the light direction.
#include "render/scene.h"

#include <gtest/gtest.h>

#include <cmath>

#include "test_util.h"

namespace nbtf {
namespace {

TEST(Scene, EveryNamedSceneHasTheBtfShapeFirstAndItsTiling) {
  EXPECT_EQ(sceneNames(), (std::vector<std::string>{"plane", "tile", "sphere", "cylinder", "cloth"}));
  const ShapeKind first[] = {ShapeKind::Rect, ShapeKind::Rect, ShapeKind::Sphere, ShapeKind::Cylinder, ShapeKind::Cloth};
  for (std::size_t i = 0; i < sceneNames().size(); ++i) {
    const Scene s = makeScene(sceneNames()[i], 3);
    SCOPED_TRACE(s.name);
    EXPECT_EQ(s.name, sceneNames()[i]);
    // The material's shape, and the grey ground or occluder; the tile is the plane alone.
    ASSERT_EQ(s.shapes.size(), s.name == "tile" ? 1u : 2u);
    EXPECT_EQ(s.shapes[0].kind, first[i]);
    EXPECT_EQ(s.shapes[0].material, 0);
    EXPECT_EQ(s.shapes[0].tiling, 3);
    if (s.shapes.size() > 1) EXPECT_EQ(s.shapes[1].material, 1);
    EXPECT_NEAR(s.toLight.x * s.toLight.x + s.toLight.y * s.toLight.y + s.toLight.z * s.toLight.z, 1, 1e-12);
    EXPECT_GT(s.toLight.y, 0);  // the default light is above the horizon
  }
}

TEST(Scene, UnknownScenesAndBadTilingsAreErrors) {
  test::expectErrorContaining([] { makeScene("teapot", 1, "--scene"); },
                              {"--scene", "unknown scene 'teapot'", "plane, tile, sphere, cylinder, cloth"});
  test::expectErrorContaining([] { makeScene("plane", 0); }, {"--tiling must be a positive number"});
  test::expectErrorContaining([] { makeScene("plane", NAN); }, {"--tiling"});
}

// theta from +y (up), phi in the ground plane from +x towards +z.
TEST(Scene, LightDirectionsAreMeasuredFromTheZenith) {
  const Vec3d up = lightVector({0, 0});
  EXPECT_NEAR(up.y, 1, 1e-12);
  EXPECT_NEAR(up.x, 0, 1e-12);
  const Vec3d x = lightVector({90, 0});
  EXPECT_NEAR(x.x, 1, 1e-12);
  EXPECT_NEAR(x.y, 0, 1e-12);
  const Vec3d z = lightVector({90, 90});
  EXPECT_NEAR(z.z, 1, 1e-12);
  EXPECT_NEAR(z.x, 0, 1e-12);
  Scene s = makeScene("sphere", 1);
  setLight(s, {60, 180});
  EXPECT_NEAR(s.toLight.x, -std::sin(60 * M_PI / 180), 1e-12);
  EXPECT_NEAR(s.toLight.y, 0.5, 1e-12);
  EXPECT_THROW(setLight(s, {95, 0}), Error);  // below the horizon
}

}  // namespace
}  // namespace nbtf
