// A fitted glTF material: per texel the metallic-roughness parameters, a tangent-space shading
// normal and optionally sheen, plus the one exposure that turns the BRDF into the BTF's values.
//
// Radiometric convention (the one `nbtf render` gives a BTF): a measured value already holds
// the light's cosine, value(l, v) = exposure x f(l, v) x max(0, n_s . l), with n_s the texel's
// shading normal. A renderer reproduces the stack's values by lighting the material with a sun
// of strength `exposure` (radiance = strength x f x cos): the file's extras carry it.
//
// Frames: light and view are unit vectors in the BTF's local frame (z = the macro normal, x
// along increasing u = texel x, y along increasing v = texel row), exactly the decoder's
// UvQuery. A glTF normal map's green channel points up the image (towards decreasing v), so
// the stored tangent-space normal is (n_x, -n_y, n_z) of this frame.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "gltf/gltf_brdf.h"

namespace nbtf::gltf {

struct TexelParams {
  BrdfParams brdf;
  Vec3 normal{0, 0, 1};  // unit shading normal, BTF frame
};

struct GltfMaterial {
  int width = 0, height = 0;
  double exposure = 1;             // sun strength that reproduces the stack's values
  bool sheen = false;              // the texels carry KHR_materials_sheen (colour, roughness)
  bool specular = false;           // the texels carry their own dielectric F0 (KHR_materials_specular)
  std::vector<TexelParams> texels;  // row-major, width x height

  const TexelParams& at(int x, int y) const { return texels[static_cast<std::size_t>(y) * width + x]; }
  // The BTF value of texel (x, y) for light `l` and view `v` (BTF frame, unit): linear RGB.
  Vec3 value(int texel, const Vec3& l, const Vec3& v) const;
};

// exposure x f x max(0, n . l), the value one parameter set gives (the fit's model).
Vec3 texelValue(const TexelParams& t, double exposure, const Vec3& l, const Vec3& v);

// The 8-bit textures a glTF file stores, and back. Quantizing a material and reading its
// textures gives the material a renderer sees; the fit reports its error on that one.
struct TextureSet {
  int width = 0, height = 0;
  std::vector<std::uint8_t> baseColor;           // RGB, sRGB-encoded
  std::vector<std::uint8_t> metallicRoughness;   // RGB: G = roughness, B = metallic (linear); R unused (255)
  std::vector<std::uint8_t> normal;              // RGB: tangent-space normal x 0.5 + 0.5 (green = up the image)
  std::vector<std::uint8_t> sheen;               // RGBA: sheen colour (sRGB), roughness in alpha (linear); empty = none
  // KHR_materials_specular's specularColorTexture (grey, sRGB) and factor: F0 = min(0.04 x
  // factor x texture, 1); empty = none (F0 0.04).
  std::vector<std::uint8_t> specular;
  double specularColorFactor = 1;
};
TextureSet quantize(const GltfMaterial& m);
// Throws nbtf::Error naming `source` when the textures' sizes do not match.
GltfMaterial dequantize(const TextureSet& t, double exposure, const std::string& source);

}  // namespace nbtf::gltf
