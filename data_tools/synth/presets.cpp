// The material presets: one pattern and its traits each. The first is the default.
#include <sstream>

#include "synth/meso_pattern.h"
#include "util/error.h"

namespace nbtf::synth {
namespace {

WeaveSpec denimTwill() {
  WeaveSpec s;
  s.kind = WeaveKind::Twill;
  s.over = 3, s.under = 1;
  s.warpPitch = 9, s.weftPitch = 9;
  s.halfWidth = 0.44, s.thickness = 0.16, s.crimp = 0.11, s.wander = 0.05, s.slub = 0.10;
  s.flatness = 2.5;
  s.warp = {{0.045f, 0.075f, 0.20f}, 0.07f, 0.18f, 28, 0.35f, 0.12f, 0.04f, 0.18f, 0.50f, 0.15f, 0.5f};
  s.weft = {{0.62f, 0.58f, 0.50f}, 0.05f, 0.12f, -24, 0.35f, 0.10f, 0.03f, 0.22f, 0.55f, 0.15f, 0.5f};
  s.gapColour[0] = 0.04f, s.gapColour[1] = 0.05f, s.gapColour[2] = 0.09f;
  return s;
}

WeaveSpec silkSatin() {
  WeaveSpec s;
  s.kind = WeaveKind::Satin;
  s.over = 4, s.under = 1;
  s.warpPitch = 4.5, s.weftPitch = 6.5;
  s.halfWidth = 0.48, s.thickness = 0.18, s.crimp = 0.10, s.wander = 0.03, s.slub = 0.04;
  s.flatness = 5;  // silk floats lie flat
  s.warp = {{0.38f, 0.24f, 0.06f}, 0.03f, 0.06f, 6, 0.5f, 0.05f, 0.05f, 0.07f, 0.30f, 0.0f, 0.5f};
  s.weft = {{0.30f, 0.20f, 0.055f}, 0.03f, 0.08f, -10, 0.5f, 0.06f, 0.03f, 0.10f, 0.35f, 0.0f, 0.5f};
  s.gapColour[0] = 0.10f, s.gapColour[1] = 0.06f, s.gapColour[2] = 0.02f;
  return s;
}

MaterialTraits traits(float exposure, float fresnelF0, float shadowHardness, float sheenTint) {
  MaterialTraits t;
  t.exposure = exposure;
  t.fresnelF0 = fresnelF0;
  t.shadowHardness = shadowHardness;
  t.sheenTint = sheenTint;
  return t;
}

}  // namespace

const std::vector<Preset>& presetTable() {
  static const std::vector<Preset> table = {
      {"fabric",
       "woven cotton twill (3/1, denim-like): indigo warp, off-white weft, twisted plied yarns, "
       "soft anisotropic sheen along the fibres",
       traits(1.0f, 0, 10, 0.6f),
       [](int w, int h, Rng& rng) { return makeWeave(denimTwill(), w, h, rng); }},
      {"wool",
       "stockinette knit of fuzzy heathered wool: plump V-shaped stitches over deep holes, "
       "strong self-shadowing and masking, mostly diffuse with a fuzz sheen",
       traits(1.1f, 0, 6, 0.7f),
       [](int w, int h, Rng& rng) { return makeKnit(w, h, rng); }},
      {"corduroy",
       "brown corduroy: rounded wales of cut pile over a woven backing, velvet sheen, "
       "weak anisotropic lobe along the wales",
       traits(1.0f, 0, 8, 0.8f),
       [](int w, int h, Rng& rng) { return makeCorduroy(w, h, rng); }},
      {"satin",
       "gold silk satin (5-harness, warp-faced): long smooth floats with a strong anisotropic "
       "highlight along the threads",
       traits(1.0f, 0, 10, 0.5f),
       [](int w, int h, Rng& rng) { return makeWeave(silkSatin(), w, h, rng); }},
      {"glossy",
       "lacquered oxblood leather: pebbled grain with creases and pores under a glossy "
       "dielectric coat (isotropic, Fresnel), sharp highlights that clip in 8-bit",
       traits(1.0f, 0.04f, 12, 0),
       [](int w, int h, Rng& rng) { return makeLeather(w, h, rng); }},
  };
  return table;
}

const Preset& findPreset(const std::string& name) {
  for (const Preset& p : presetTable())
    if (p.name == name) return p;
  std::ostringstream s;
  s << "unknown preset '" << name << "' (available:";
  for (const Preset& p : presetTable()) s << " " << p.name;
  s << ")";
  throw Error(s.str());
}

}  // namespace nbtf::synth
