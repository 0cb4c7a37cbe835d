// The glTF 2.0 metallic-roughness BRDF (the specification's Appendix B) and the sheen lobe of
// KHR_materials_sheen, in the local shading frame (z = the shading normal). This is what every
// glTF renderer approximates: Lambertian diffuse, GGX (Trowbridge-Reitz) distribution with the
// height-correlated Smith visibility, Schlick's Fresnel with F0 = 0.04 for dielectrics (another
// F0 with KHR_materials_specular: a white specular colour, specularFactor 1) and the base colour
// for metals; sheen is the Charlie distribution with Ashikhmin's visibility, and
// scales the base layer by 1 - max(sheen colour) x 0.157 (the extension's simple albedo
// scaling).
#pragma once
#include <array>

namespace nbtf::gltf {

using Vec3 = std::array<double, 3>;

// A dielectric's F0 at the specification's IOR 1.5.
constexpr double kDielectricF0 = 0.04;

struct BrdfParams {
  Vec3 baseColor{0.5, 0.5, 0.5};  // linear RGB in [0, 1]
  double metallic = 0;             // [0, 1]
  double roughness = 0.5;          // perceptual roughness [0, 1]; alpha = roughness^2
  Vec3 sheenColor{0, 0, 0};        // linear RGB; all zero = no sheen
  double sheenRoughness = 0;       // [0, 1]
  double specularF0 = kDielectricF0;  // the dielectric's F0: 0.04 (IOR 1.5) x KHR_materials_specular's colour
};

// The smallest alpha the evaluation uses (roughness 0 is a mirror: a delta no finite set of
// measured directions can show; the fit keeps roughness above sqrt of this).
constexpr double kMinAlpha = 1e-3;
// Sheen's albedo scaling: the base layer is multiplied by 1 - max(sheenColor) * this.
constexpr double kSheenAlbedoScale = 0.157;

// f(l, v) for unit vectors `l` (towards the light) and `v` (towards the viewer) in the frame of
// the unit shading normal `n`; zero when either is below the shading horizon. RGB, 1/sr.
Vec3 evaluateBrdf(const BrdfParams& p, const Vec3& n, const Vec3& l, const Vec3& v);

// The GGX distribution D(h) and the height-correlated visibility V = G / (4 |n.l| |n.v|), as
// the specification writes them (exposed for the tests' hand-computed points).
double ggxDistribution(double alpha, double nDotH);
double smithVisibility(double alpha, double nDotL, double nDotV);
// Charlie distribution and Ashikhmin visibility of the sheen lobe.
double charlieDistribution(double sheenRoughness, double nDotH);
double sheenVisibility(double nDotL, double nDotV);

}  // namespace nbtf::gltf
