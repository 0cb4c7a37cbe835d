// Meso-structure patterns: what the surface of a material looks like at one point
// (height, diffuse colour, fibre direction, gloss), as a pure function of position.
// Each preset is one pattern plus a few material-wide traits.
#pragma once
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "synth/noise.h"

namespace nbtf::synth {

// One point of the surface, as the pattern describes it (before normals are known).
struct SurfacePoint {
  float height = 0;                  // texels, positive out of the surface
  float albedo[3] = {0, 0, 0};       // diffuse reflectance, linear sRGB, in [0, 1)
  float tangent[2] = {1, 0};         // in-plane fibre direction, image axes (x right, y down)
  float ks = 0;                      // weight of the anisotropic Ward lobe
  float alphaT = 0.3f, alphaB = 0.3f;  // Ward roughness along / across the fibre direction
  float sheen = 0;                   // weight of the cloth sheen lobe (fibres seen edge-on)
  float sheenRoughness = 0.5f;       // in (0, 1]: 1 = broad sheen, small = tight grazing rim
};

// Material-wide parameters of a preset.
struct MaterialTraits {
  float exposure = 1;         // scales every value (the light's irradiance at normal incidence)
  float fresnelF0 = 0;        // > 0: the glossy lobe is a dielectric coat with Schlick Fresnel, normalized to
                              // 1 at normal incidence (glancing highlights grow); 0: no Fresnel (cloth)
  float shadowHardness = 10;  // soft-shadow constant: the penumbra spans about 1/hardness radians
  float bounce = 1;           // strength of the one-bounce interreflection estimate (1 = as derived)
  float sheenTint = 0.5f;     // sheen colour: 0 = white, 1 = the albedo
};

// A pattern is evaluated at image positions x (column) and y (row) in texels; it is
// periodic with the image size so the material tiles without seams.
class MesoPattern {
 public:
  virtual ~MesoPattern() = default;
  virtual SurfacePoint eval(double x, double y) const = 0;
};

struct Preset {
  std::string name;
  std::string description;
  MaterialTraits traits;
  std::function<std::unique_ptr<MesoPattern>(int width, int height, Rng& rng)> make;
};

// The preset table (presets.cpp); findPreset throws nbtf::Error listing the names.
const std::vector<Preset>& presetTable();
const Preset& findPreset(const std::string& name);

// ---- Pattern families (one file each) ----------------------------------------------

// Look of one yarn system (warp or weft).
struct YarnLook {
  float colour[3];
  float colourJitter;   // per-thread relative brightness variation
  float streaks;        // relative albedo variation of fibre streaks along the thread
  float twistDeg;       // surface fibre angle to the yarn axis (ply twist)
  float plyPeriod;      // spacing of the ply ridges, in thread pitches
  float plyDepth;       // ply ridge height, relative to the thread thickness
  float ks, alphaT, alphaB, sheen, sheenRoughness;
};

enum class WeaveKind { Plain, Twill, Satin };
struct WeaveSpec {
  WeaveKind kind = WeaveKind::Plain;
  int over = 1, under = 1;     // twill n/m; satin: harness = over + under, under = 1
  double warpPitch = 8;        // target texels between warp threads (rounded to tile)
  double weftPitch = 8;
  double halfWidth = 0.42;     // thread half-width, fraction of its pitch
  double thickness = 0.22;     // thread half-height, fraction of the mean pitch
  double flatness = 2;         // cross-section (1 - |s|^p)^(1/p): 2 = ellipse, larger = flatter top
  double crimp = 0.16;         // over/under undulation amplitude, fraction of the mean pitch
  double wander = 0.05;        // thread path irregularity, fraction of the pitch
  double slub = 0.08;          // thickness irregularity along a thread
  YarnLook warp, weft;
  float gapColour[3];          // what is seen through the gaps between threads
};
std::unique_ptr<MesoPattern> makeWeave(const WeaveSpec& spec, int width, int height, Rng& rng);

std::unique_ptr<MesoPattern> makeKnit(int width, int height, Rng& rng);
std::unique_ptr<MesoPattern> makeCorduroy(int width, int height, Rng& rng);
std::unique_ptr<MesoPattern> makeLeather(int width, int height, Rng& rng);

// ---- Helpers shared by the patterns -------------------------------------------------

// Number of pattern repeats of `pitch` texels across `size` texels, a positive multiple
// of `multiple` (so a weave repeat fits the tile exactly).
int repeatsAcross(int size, double pitch, int multiple = 1);

// Evaluates tileable noise at image position (x, y) of a width x height image: one
// lattice period spans the image, whatever the lattice periods are.
template <class Noise>
float tileNoise(const Noise& n, double x, double y, int width, int height) {
  return n.eval(x / width * n.periodX(), y / height * n.periodY());
}

// Ply ridges of a twisted yarn: height modulation in [-1, 1] and the surface fibre
// direction (image axes) at `rel`, a point relative to the yarn's axis in image texels.
// The ridges run along the fibres, at `twistDeg` to the axis, `spacing` texels apart.
// tileLength > 0 snaps the ridge period along the axis so that it divides tileLength
// (for threads that run through the whole tile).
struct PlyResult {
  float ridge;
  float tangent[2];
};
PlyResult plyRidges(const double rel[2], const double axis[2], double twistDeg, double spacing, double tileLength = 0);

float smoothstep(float edge0, float edge1, float x);

}  // namespace nbtf::synth
