#include "gltf/gltf_material.h"

#include <algorithm>
#include <cmath>

#include "io/color.h"
#include "util/error.h"

namespace nbtf::gltf {
namespace {
std::uint8_t unitTo8(double x) { return static_cast<std::uint8_t>(std::lround(std::clamp(x, 0.0, 1.0) * 255)); }
double unitFrom8(std::uint8_t b) { return b / 255.0; }
}  // namespace

Vec3 texelValue(const TexelParams& t, double exposure, const Vec3& l, const Vec3& v) {
  const Vec3& n = t.normal;
  const double cosL = n[0] * l[0] + n[1] * l[1] + n[2] * l[2];
  if (cosL <= 0) return {0, 0, 0};
  Vec3 f = evaluateBrdf(t.brdf, n, l, v);
  for (double& c : f) c *= exposure * cosL;
  return f;
}

Vec3 GltfMaterial::value(int texel, const Vec3& l, const Vec3& v) const {
  return texelValue(texels[static_cast<std::size_t>(texel)], exposure, l, v);
}

TextureSet quantize(const GltfMaterial& m) {
  TextureSet t;
  t.width = m.width, t.height = m.height;
  const std::size_t n = m.texels.size();
  double f0Max = 0;  // the texture spans [0, the largest F0]; the factor carries the rest
  for (const TexelParams& p : m.texels) f0Max = std::max(f0Max, p.brdf.specularF0);
  if (m.specular) {
    t.specular.resize(3 * n);
    t.specularColorFactor = std::max(f0Max, 1e-3) / kDielectricF0;
  }
  t.baseColor.resize(3 * n), t.metallicRoughness.resize(3 * n), t.normal.resize(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const TexelParams& p = m.texels[i];
    for (int c = 0; c < 3; ++c) t.baseColor[3 * i + c] = linearToSrgb8(static_cast<float>(p.brdf.baseColor[c]));
    t.metallicRoughness[3 * i] = 255;
    t.metallicRoughness[3 * i + 1] = unitTo8(p.brdf.roughness);
    t.metallicRoughness[3 * i + 2] = unitTo8(p.brdf.metallic);
    const Vec3 stored{p.normal[0], -p.normal[1], p.normal[2]};
    for (int c = 0; c < 3; ++c) t.normal[3 * i + c] = unitTo8(stored[c] * 0.5 + 0.5);
    if (m.specular) {
      const float grey = static_cast<float>(p.brdf.specularF0 / (kDielectricF0 * t.specularColorFactor));
      for (int c = 0; c < 3; ++c) t.specular[3 * i + c] = linearToSrgb8(grey);
    }
    if (m.sheen) {
      if (t.sheen.empty()) t.sheen.resize(4 * n);
      for (int c = 0; c < 3; ++c) t.sheen[4 * i + c] = linearToSrgb8(static_cast<float>(p.brdf.sheenColor[c]));
      t.sheen[4 * i + 3] = unitTo8(p.brdf.sheenRoughness);
    }
  }
  return t;
}

GltfMaterial dequantize(const TextureSet& t, double exposure, const std::string& source) {
  const std::size_t n = static_cast<std::size_t>(t.width) * t.height;
  if (t.width <= 0 || t.height <= 0 || t.baseColor.size() != 3 * n || t.metallicRoughness.size() != 3 * n ||
      t.normal.size() != 3 * n || (!t.sheen.empty() && t.sheen.size() != 4 * n) ||
      (!t.specular.empty() && t.specular.size() != 3 * n))
    throw fileError(source, "the base colour, metallic-roughness, normal and sheen textures must have the same size");
  GltfMaterial m;
  m.width = t.width, m.height = t.height, m.exposure = exposure;
  m.sheen = !t.sheen.empty();
  m.specular = !t.specular.empty();
  m.texels.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    TexelParams& p = m.texels[i];
    for (int c = 0; c < 3; ++c) p.brdf.baseColor[c] = srgb8ToLinear(t.baseColor[3 * i + c]);
    p.brdf.roughness = unitFrom8(t.metallicRoughness[3 * i + 1]);
    p.brdf.metallic = unitFrom8(t.metallicRoughness[3 * i + 2]);
    Vec3 nm{unitFrom8(t.normal[3 * i]) * 2 - 1, -(unitFrom8(t.normal[3 * i + 1]) * 2 - 1),
            unitFrom8(t.normal[3 * i + 2]) * 2 - 1};
    const double len = std::sqrt(nm[0] * nm[0] + nm[1] * nm[1] + nm[2] * nm[2]);
    p.normal = len > 1e-6 ? Vec3{nm[0] / len, nm[1] / len, nm[2] / len} : Vec3{0, 0, 1};
    if (m.specular)
      p.brdf.specularF0 = std::min(1.0, kDielectricF0 * t.specularColorFactor * srgb8ToLinear(t.specular[3 * i]));
    if (m.sheen) {
      for (int c = 0; c < 3; ++c) p.brdf.sheenColor[c] = srgb8ToLinear(t.sheen[4 * i + c]);
      p.brdf.sheenRoughness = unitFrom8(t.sheen[4 * i + 3]);
    }
  }
  return m;
}

}  // namespace nbtf::gltf
