// The pinhole camera (render/camera.cpp): `--camera` text, and rays through the image plane.
#include "render/camera.h"

#include <gtest/gtest.h>

#include <cmath>

#include "test_util.h"

namespace nbtf {
namespace {

TEST(Camera, ParsesThreeSixOrSevenNumbersOverTheBase) {
  CameraSpec base;
  base.target = {0, 1, 0};
  base.fovDeg = 30;
  const CameraSpec eye = parseCamera("1, 2,3", base, "--camera");
  EXPECT_EQ(eye.eye.x, 1);
  EXPECT_EQ(eye.eye.y, 2);
  EXPECT_EQ(eye.eye.z, 3);
  EXPECT_EQ(eye.target.y, 1);  // the base's
  EXPECT_EQ(eye.fovDeg, 30);
  const CameraSpec all = parseCamera("0,1,5,0,0.5,0,55", base, "--camera");
  EXPECT_EQ(all.target.y, 0.5);
  EXPECT_EQ(all.fovDeg, 55);
  EXPECT_EQ(parseCamera("0,1,5,1,0,0", base, "--camera").fovDeg, 30);
}

TEST(Camera, BadCamerasAreNamedErrors) {
  const CameraSpec base;
  test::expectErrorContaining([&] { parseCamera("1,2,x", base, "--camera"); }, {"--camera", "'x' is not a number"});
  test::expectErrorContaining([&] { parseCamera("1,2,3,4", base, "--camera"); }, {"--camera", "got 4"});
  test::expectErrorContaining([&] { parseCamera("1,2,inf", base, "--camera"); }, {"'inf' is not a number"});
  test::expectErrorContaining([&] { parseCamera("0,1,5,0,0,0,170", base, "--view"); },
                              {"--view", "field of view must be in (0, 170)"});
  test::expectErrorContaining([&] { parseCamera("0,0.5,0", base, "--camera"); }, {"the same point"});
  test::expectErrorContaining([&] { parseCamera("0,5,0,0,0,0", base, "--camera"); }, {"straight up or down"});
  test::expectErrorContaining([&] { Camera(base, 0, 10); }, {"at least 1x1"});
}

// The image centre looks at the target; the top edge is the field of view up, the right edge
// the field of view times the aspect to the right; rays are unit length from the eye.
TEST(Camera, RaysSpanTheFieldOfViewFromTheEye) {
  const CameraSpec spec{{0, 0, 5}, {0, 0, 0}, 60};
  const Camera cam(spec, 200, 100);
  const Ray<double> centre = cam.ray(100.0, 50.0);
  EXPECT_EQ(centre.origin.z, 5);
  EXPECT_NEAR(centre.dir.x, 0, 1e-12);
  EXPECT_NEAR(centre.dir.y, 0, 1e-12);
  EXPECT_NEAR(centre.dir.z, -1, 1e-12);
  const Ray<double> top = cam.ray(100.0, 0.0);
  EXPECT_NEAR(std::atan2(top.dir.y, -top.dir.z), 30 * M_PI / 180, 1e-12);
  EXPECT_NEAR(top.dir.x, 0, 1e-12);
  const Ray<double> right = cam.ray(200.0, 50.0);
  EXPECT_NEAR(right.dir.x / -right.dir.z, 2 * std::tan(30 * M_PI / 180), 1e-12);  // aspect 2
  EXPECT_GT(right.dir.x, 0);  // +x is to the right, looking down -z
  for (const Ray<double>& r : {centre, top, right})
    EXPECT_NEAR(r.dir.x * r.dir.x + r.dir.y * r.dir.y + r.dir.z * r.dir.z, 1, 1e-12);
  EXPECT_EQ(cam.width(), 200);
  EXPECT_EQ(cam.height(), 100);
}

}  // namespace
}  // namespace nbtf
