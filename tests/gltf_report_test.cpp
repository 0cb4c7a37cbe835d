// The fit's error (gltf/gltf_report.h): RMSE over every image, divided by alpha, overall and
// by elevation band; the ground truth read beside a stack.
#include "gltf/gltf_report.h"

#include <gtest/gtest.h>

#include <cmath>

#include "test_util.h"

namespace nbtf::gltf {
namespace {

GltfMaterial grey() {
  GltfMaterial m;
  m.width = 3, m.height = 2, m.exposure = 3.14159265358979;
  m.texels.resize(6);
  return m;
}

// The material's own images, plus `offset` on every value of images lit from theta >= 60.
ImageSource shifted(const GltfMaterial& m, double offset) {
  return [m, offset](int image, float* rgb) {
    const auto& dirs = hemisphere81();
    const Direction& ld = dirs[image / 81];
    const auto l = ld.unitVector(), v = dirs[image % 81].unitVector();
    for (int t = 0; t < 6; ++t) {
      const Vec3 value = m.value(t, {l[0], l[1], l[2]}, {v[0], v[1], v[2]});
      for (int c = 0; c < 3; ++c) rgb[3 * t + c] = static_cast<float>(value[c] + (ld.thetaDeg >= 60 ? offset : 0));
    }
  };
}

TEST(GltfReport, ErrorsAreRmseOverAlphaOverallAndByElevation) {
  const GltfMaterial m = grey();
  const std::vector<Reference> refs = {{"same", "a", shifted(m, 0)}, {"shifted", "b", shifted(m, 0.1)}};
  const std::vector<FitError> e = measureFitErrors(m, hemisphere81(), hemisphere81(), refs, 0.5, false);
  ASSERT_EQ(e.size(), 2u);
  EXPECT_NEAR(e[0].rmse, 0, 1e-7);
  // Lights at theta 60 and 75: 20 + 24 of 81. Error 0.1 there, 0 elsewhere; / alpha 0.5.
  EXPECT_NEAR(e[1].rmse, std::sqrt(0.01 * 44 / 81) / 0.5, 1e-6);
  ASSERT_EQ(e[1].byLight.size(), 6u);
  EXPECT_NEAR(e[1].byLight[0].rmse, 0, 1e-7);
  EXPECT_NEAR(e[1].byLight[4].rmse, 0.2, 1e-6);
  EXPECT_EQ(e[1].byLight[4].thetaFromDeg, 60);
  EXPECT_EQ(e[1].byLight[4].values, 20u * 81 * 6 * 3);
  for (const ElevationBand& b : e[1].byView) EXPECT_NEAR(b.rmse, e[1].rmse, 1e-6);  // the same for every view
  test::expectErrorContaining([&] { measureFitErrors(m, hemisphere81(), hemisphere81(), refs, 0, false); }, {"alpha"});
}

TEST(GltfReport, ANonFiniteReferenceValueIsNamed) {
  const GltfMaterial m = grey();
  const std::vector<Reference> refs = {{"bad", "bad.exr", [](int, float* rgb) {
                                          for (int i = 0; i < 18; ++i) rgb[i] = i == 4 ? NAN : 0.f;
                                        }}};
  test::expectErrorContaining([&] { measureFitErrors(m, hemisphere81(), hemisphere81(), refs, 1, false); },
                              {"bad.exr", "non-finite"});
}

}  // namespace
}  // namespace nbtf::gltf
