// The glTF 2.0 BRDF (gltf/gltf_brdf.h) against the specification's formulas at hand-computed
// points, and its symmetries.
#include "gltf/gltf_brdf.h"

#include <gtest/gtest.h>

#include <cmath>

namespace nbtf::gltf {
namespace {

constexpr double kPi = 3.14159265358979323846;
const Vec3 kUp{0, 0, 1};

Vec3 unit(double thetaDeg, double phiDeg) {
  const double t = thetaDeg * kPi / 180, p = phiDeg * kPi / 180;
  return {std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t)};
}

TEST(GltfBrdf, DistributionAndVisibilityAtHandComputedPoints) {
  // D = a^2 / (pi ((n.h)^2 (a^2 - 1) + 1)^2): at n.h = 1 it is 1 / (pi a^2).
  EXPECT_NEAR(ggxDistribution(0.25, 1), 1 / (kPi * 0.0625), 1e-12);
  // n.h = 0.8, a = 0.5: a^2 = 0.25; 0.64 (-0.75) + 1 = 0.52; 0.25 / (pi 0.2704).
  EXPECT_NEAR(ggxDistribution(0.5, 0.8), 0.25 / (kPi * 0.52 * 0.52), 1e-12);
  EXPECT_EQ(ggxDistribution(0.5, -0.1), 0);
  // V = 0.5 / (n.l sqrt((n.v)^2 (1 - a^2) + a^2) + n.v sqrt((n.l)^2 (1 - a^2) + a^2)).
  EXPECT_NEAR(smithVisibility(0.5, 1, 1), 0.25, 1e-12);
  const double nl = 0.6, nv = 0.9, a2 = 0.09;
  EXPECT_NEAR(smithVisibility(0.3, nl, nv),
              0.5 / (nl * std::sqrt(nv * nv * (1 - a2) + a2) + nv * std::sqrt(nl * nl * (1 - a2) + a2)), 1e-12);
  // Charlie: (2 + 1/a) sin(theta_h)^(1/a) / (2 pi), a = sheenRoughness^2; Ashikhmin: 1 / (4 (nl + nv - nl nv)).
  EXPECT_NEAR(charlieDistribution(0.5, 0), (2 + 4) / (2 * kPi), 1e-12);
  EXPECT_NEAR(charlieDistribution(0.5, 0.6), 6 * std::pow(0.64, 2.0) / (2 * kPi), 1e-12);
  EXPECT_NEAR(sheenVisibility(1, 1), 0.25, 1e-12);
  EXPECT_NEAR(sheenVisibility(0.5, 0.5), 1 / (4 * 0.75), 1e-12);
}

TEST(GltfBrdf, NormalIncidenceMixesDiffuseAndSpecularAsTheSpecificationSays) {
  BrdfParams p;
  p.baseColor = {0.5, 0.25, 1.0};
  p.roughness = 0.5;  // alpha 0.25
  // l = v = n: v.h = 1, so Schlick's term is 0: F = 0.04 (dielectric) or the base colour (metal).
  const double dv = (1 / (kPi * 0.0625)) * 0.25;
  const Vec3 d = evaluateBrdf(p, kUp, kUp, kUp);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(d[c], 0.96 * p.baseColor[c] / kPi + 0.04 * dv, 1e-12) << c;
  p.metallic = 1;
  const Vec3 m = evaluateBrdf(p, kUp, kUp, kUp);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(m[c], dv * p.baseColor[c], 1e-12) << c;
  p.metallic = 0.25;
  const Vec3 mix = evaluateBrdf(p, kUp, kUp, kUp);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(mix[c], 0.75 * d[c] + 0.25 * m[c], 1e-12) << c;
}

TEST(GltfBrdf, ASpecularF0ReplacesTheDielectricsFourPercent) {
  BrdfParams p;
  p.baseColor = {0.5, 0.5, 0.5};
  p.roughness = 0.5;
  p.specularF0 = 0.1;
  const double dv = (1 / (kPi * 0.0625)) * 0.25;
  EXPECT_NEAR(evaluateBrdf(p, kUp, kUp, kUp)[0], 0.9 * 0.5 / kPi + 0.1 * dv, 1e-12);
}

TEST(GltfBrdf, GrazingFresnelFollowsSchlick) {
  BrdfParams p;
  p.baseColor = {0, 0, 0};
  p.roughness = 0.6;
  const Vec3 l = unit(60, 0), v = unit(60, 180);  // mirror pair: h = n, v.h = cos 60 = 0.5
  const double alpha = 0.36, nl = 0.5, nv = 0.5;
  const double f = 0.04 + 0.96 * std::pow(0.5, 5);
  const Vec3 got = evaluateBrdf(p, kUp, l, v);
  EXPECT_NEAR(got[0], f * ggxDistribution(alpha, 1) * smithVisibility(alpha, nl, nv), 1e-12);
}

TEST(GltfBrdf, IsReciprocalAndZeroBelowTheHorizon) {
  BrdfParams p;
  p.baseColor = {0.3, 0.6, 0.2};
  p.metallic = 0.4, p.roughness = 0.35, p.sheenColor = {0.2, 0.1, 0.3}, p.sheenRoughness = 0.6;
  const Vec3 n = unit(10, 30);
  for (double tl : {5.0, 40.0, 70.0})
    for (double tv : {0.0, 35.0, 65.0}) {
      const Vec3 a = evaluateBrdf(p, n, unit(tl, 20), unit(tv, 200)), b = evaluateBrdf(p, n, unit(tv, 200), unit(tl, 20));
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], b[c], 1e-12 * (1 + std::abs(a[c])));
    }
  const Vec3 below{0.5, 0, -0.8660254};
  EXPECT_EQ(evaluateBrdf(p, kUp, below, kUp)[0], 0);
  EXPECT_EQ(evaluateBrdf(p, kUp, kUp, below)[1], 0);
}

TEST(GltfBrdf, AWhiteRoughDielectricReflectsNoMoreThanItReceives) {
  // Directional albedo: the integral of f cos(theta_v) over the hemisphere, at normal light.
  BrdfParams p;
  p.baseColor = {1, 1, 1};
  p.roughness = 1;
  double albedo = 0;
  const int steps = 200;
  for (int i = 0; i < steps; ++i)
    for (int j = 0; j < 2 * steps; ++j) {
      const double t = (i + 0.5) * (kPi / 2) / steps, ph = (j + 0.5) * kPi / steps;
      const Vec3 v{std::sin(t) * std::cos(ph), std::sin(t) * std::sin(ph), std::cos(t)};
      albedo += evaluateBrdf(p, kUp, kUp, v)[0] * std::cos(t) * std::sin(t) * (kPi / 2 / steps) * (kPi / steps);
    }
  EXPECT_LE(albedo, 1.0);
  EXPECT_GT(albedo, 0.9);  // Lambertian 0.96 plus the specular lobe, less its shadowing
}

}  // namespace
}  // namespace nbtf::gltf
