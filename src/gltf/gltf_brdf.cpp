#include "gltf/gltf_brdf.h"

#include <algorithm>
#include <cmath>

namespace nbtf::gltf {
namespace {
constexpr double kPi = 3.14159265358979323846;
double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
}  // namespace

double ggxDistribution(double alpha, double nDotH) {
  if (nDotH <= 0) return 0;
  const double a2 = alpha * alpha;
  const double d = nDotH * nDotH * (a2 - 1) + 1;
  return a2 / (kPi * d * d);
}

double smithVisibility(double alpha, double nDotL, double nDotV) {
  const double a2 = alpha * alpha;
  const double gl = nDotV * std::sqrt(nDotL * nDotL * (1 - a2) + a2);
  const double gv = nDotL * std::sqrt(nDotV * nDotV * (1 - a2) + a2);
  const double s = gl + gv;
  return s > 0 ? 0.5 / s : 0;
}

double charlieDistribution(double sheenRoughness, double nDotH) {
  if (nDotH < 0) return 0;
  const double alpha = std::max(sheenRoughness * sheenRoughness, kMinAlpha);
  const double inv = 1 / alpha;
  const double sin2 = std::max(0.0, 1 - nDotH * nDotH);
  return (2 + inv) * std::pow(sin2, 0.5 * inv) / (2 * kPi);
}

double sheenVisibility(double nDotL, double nDotV) {
  const double d = 4 * (nDotL + nDotV - nDotL * nDotV);
  return d > 0 ? 1 / d : 0;
}

Vec3 evaluateBrdf(const BrdfParams& p, const Vec3& n, const Vec3& l, const Vec3& v) {
  const double nl = dot(n, l), nv = dot(n, v);
  if (nl <= 0 || nv <= 0) return {0, 0, 0};
  Vec3 h{l[0] + v[0], l[1] + v[1], l[2] + v[2]};
  const double hl = std::sqrt(dot(h, h));
  if (!(hl > 0)) return {0, 0, 0};
  for (double& c : h) c /= hl;
  const double nh = dot(n, h), vh = std::abs(dot(v, h));
  const double alpha = std::max(p.roughness * p.roughness, kMinAlpha);
  const double specular = ggxDistribution(alpha, nh) * smithVisibility(alpha, nl, nv);
  const double schlick = std::pow(1 - vh, 5);
  const double dielectricF = p.specularF0 + (1 - p.specularF0) * schlick;
  double sheenMax = std::max({p.sheenColor[0], p.sheenColor[1], p.sheenColor[2]});
  double sheen = 0;
  if (sheenMax > 0) sheen = charlieDistribution(p.sheenRoughness, nh) * sheenVisibility(nl, nv);
  const double baseScale = 1 - sheenMax * kSheenAlbedoScale;
  Vec3 f{};
  for (int c = 0; c < 3; ++c) {
    const double base = p.baseColor[c];
    const double dielectric = (1 - dielectricF) * base / kPi + dielectricF * specular;
    const double metal = specular * (base + (1 - base) * schlick);
    f[c] = baseScale * ((1 - p.metallic) * dielectric + p.metallic * metal) + p.sheenColor[c] * sheen;
  }
  return f;
}

}  // namespace nbtf::gltf
