// SynthMaterial: builds the sampled surface of a preset and shades it for a light/view
// pair. Shading per fine sample (all terms times the exposure):
//   albedo * (E + occlusion * bounce * meanAlbedo * meanE)      diffuse, direct + one bounce
//   + E * wardWeight * exp(-(h.t^2/at^2 + h.b^2/ab^2) / h.n^2) * F / sqrt(cosL cosV)
//   + E * sheenWeight * sin(theta_h)^(1/r) / (4 (cosL + cosV - cosL cosV)) * sheenColour
// where E = max(0, n.l) * shadow visibility is the irradiance (the cos(theta_l) falloff),
// the Ward and Charlie-sheen lobes appear as pi * f * E, and F is Schlick's Fresnel
// normalized to 1 at normal incidence (coated presets only). A texel averages its fine
// samples; with parallax each fine sample shows the surface point its view ray hits.
#include <algorithm>
#include <cmath>
#include <sstream>

#include "synth/surface.h"
#include "synth/synth_material.h"
#include "util/error.h"

namespace nbtf::synth {

struct SynthMaterial::LightPass {
  Direction direction;
  double dir[3];
  std::vector<float> irradiance;  // per fine sample: max(0, n.l) * visibility
  float meanIrradiance = 0;
};

struct SynthMaterial::ViewPass {
  Direction direction;
  double dir[3];
  std::vector<std::uint32_t> hits;  // per fine sample: the sample its view ray shows
  std::vector<float> masking;       // without parallax: visibility toward the viewer
};

struct SynthMaterial::Impl {
  std::string preset;
  RenderSettings settings;
  MaterialTraits traits;
  int width = 0, height = 0;
  std::unique_ptr<Surface> surface;
};

// ---- Presets --------------------------------------------------------------------------

std::vector<std::string> presetNames() {
  std::vector<std::string> names;
  for (const Preset& p : presetTable()) names.push_back(p.name);
  return names;
}

std::string presetDescription(const std::string& preset) { return findPreset(preset).description; }

// ---- Construction -------------------------------------------------------------------------

namespace {
void checkSize(int size, const char* what) {
  if (size < kMinSize || size > kMaxSize) {
    std::ostringstream s;
    s << "material " << what << " " << size << " is out of range (" << kMinSize << " to " << kMaxSize << " texels)";
    throw Error(s.str());
  }
}
}  // namespace

SynthMaterial::SynthMaterial(const std::string& preset, int width, int height, std::uint64_t seed)
    : SynthMaterial(preset, width, height, seed, RenderSettings{}) {}

SynthMaterial::SynthMaterial(const std::string& preset, int width, int height, std::uint64_t seed,
                             const RenderSettings& settings)
    : impl_(std::make_unique<Impl>()) {
  const Preset& def = findPreset(preset);
  checkSize(width, "width");
  checkSize(height, "height");
  if (settings.supersampling < 1 || settings.supersampling > 4)
    throw Error("supersampling " + std::to_string(settings.supersampling) + " is out of range (1 to 4)");
  impl_->preset = preset;
  impl_->settings = settings;
  impl_->traits = def.traits;
  impl_->width = width, impl_->height = height;
  Rng rng(seed);
  std::unique_ptr<MesoPattern> pattern = def.make(width, height, rng);
  impl_->surface = std::make_unique<Surface>(*pattern, width, height, settings.supersampling);
}

SynthMaterial::~SynthMaterial() = default;
SynthMaterial::SynthMaterial(SynthMaterial&&) noexcept = default;
int SynthMaterial::width() const { return impl_->width; }
int SynthMaterial::height() const { return impl_->height; }
const std::string& SynthMaterial::preset() const { return impl_->preset; }
const RenderSettings& SynthMaterial::settings() const { return impl_->settings; }

std::vector<float> SynthMaterial::heightMap() const {
  const Surface& s = *impl_->surface;
  int ss = s.supersampling();
  std::vector<float> out(static_cast<std::size_t>(impl_->width) * impl_->height, 0.0f);
  for (int y = 0; y < impl_->height; ++y)
    for (int x = 0; x < impl_->width; ++x) {
      float sum = 0;
      for (int sy = 0; sy < ss; ++sy)
        for (int sx = 0; sx < ss; ++sx)
          sum += s.sampleHeight(static_cast<std::size_t>(y * ss + sy) * s.fineWidth() + x * ss + sx);
      out[static_cast<std::size_t>(y) * impl_->width + x] = sum / (ss * ss);
    }
  return out;
}

// ---- Light and view passes -------------------------------------------------------------------

std::shared_ptr<const SynthMaterial::LightPass> SynthMaterial::prepareLight(const Direction& light) const {
  checkHemisphere(light, "light");
  const Surface& s = *impl_->surface;
  auto pass = std::make_shared<LightPass>();
  pass->direction = light;
  auto u = light.unitVector();
  std::copy(u.begin(), u.end(), pass->dir);
  pass->irradiance.resize(s.numSamples());
  double sum = 0;
  for (std::size_t i = 0; i < s.numSamples(); ++i) {
    const float* n = s.point(i).normal;
    double cosL = n[0] * pass->dir[0] + n[1] * pass->dir[1] + n[2] * pass->dir[2];
    float e = 0;
    if (cosL > 0) {
      e = static_cast<float>(cosL);
      if (impl_->settings.shadows) e *= s.visibility(i, pass->dir, impl_->traits.shadowHardness);
    }
    pass->irradiance[i] = e;
    sum += e;
  }
  pass->meanIrradiance = static_cast<float>(sum / s.numSamples());
  return pass;
}

std::shared_ptr<const SynthMaterial::ViewPass> SynthMaterial::prepareView(const Direction& view) const {
  checkHemisphere(view, "view");
  const Surface& s = *impl_->surface;
  auto pass = std::make_shared<ViewPass>();
  pass->direction = view;
  auto u = view.unitVector();
  std::copy(u.begin(), u.end(), pass->dir);
  pass->hits.resize(s.numSamples());
  if (impl_->settings.parallax) {
    for (std::size_t i = 0; i < s.numSamples(); ++i) pass->hits[i] = static_cast<std::uint32_t>(s.parallaxHit(i, pass->dir));
  } else {
    // The texel below, darkened where the height field hides it (a point viewer: hard edge).
    pass->masking.resize(s.numSamples());
    for (std::size_t i = 0; i < s.numSamples(); ++i) {
      pass->hits[i] = static_cast<std::uint32_t>(i);
      pass->masking[i] = s.visibility(i, pass->dir, 4 * impl_->traits.shadowHardness);
    }
  }
  return pass;
}

// ---- Shading ----------------------------------------------------------------------------------

void SynthMaterial::render(const Direction& light, const Direction& view, float* rgb) const {
  render(*prepareLight(light), *prepareView(view), rgb);
}

void SynthMaterial::render(const LightPass& lightPass, const ViewPass& viewPass, float* rgb) const {
  const Surface& s = *impl_->surface;
  const MaterialTraits& traits = impl_->traits;
  const int ss = s.supersampling(), fineW = s.fineWidth();
  const float L[3] = {static_cast<float>(lightPass.dir[0]), static_cast<float>(lightPass.dir[1]),
                      static_cast<float>(lightPass.dir[2])};
  const float V[3] = {static_cast<float>(viewPass.dir[0]), static_cast<float>(viewPass.dir[1]),
                      static_cast<float>(viewPass.dir[2])};
  float H[3] = {L[0] + V[0], L[1] + V[1], L[2] + V[2]};
  float hLength = std::sqrt(H[0] * H[0] + H[1] * H[1] + H[2] * H[2]);
  if (hLength < 1e-6f) H[0] = 0, H[1] = 0, H[2] = 1;  // opposite directions: no mirror configuration
  else H[0] /= hLength, H[1] /= hLength, H[2] /= hLength;
  float fresnel = 1;
  if (traits.fresnelF0 > 0) {
    float lh = std::clamp(L[0] * H[0] + L[1] * H[1] + L[2] * H[2], 0.0f, 1.0f);
    float f = traits.fresnelF0 + (1 - traits.fresnelF0) * std::pow(1 - lh, 5.0f);
    fresnel = f / traits.fresnelF0;
  }
  float indirect[3];
  float bounce = impl_->settings.interreflection ? traits.bounce : 0.0f;
  for (int k = 0; k < 3; ++k) indirect[k] = bounce * s.meanAlbedo()[k] * lightPass.meanIrradiance;
  const float scale = traits.exposure / static_cast<float>(ss * ss);
  const bool masked = !viewPass.masking.empty();

  for (int y = 0; y < impl_->height; ++y) {
    for (int x = 0; x < impl_->width; ++x) {
      float acc[3] = {0, 0, 0};
      for (int sy = 0; sy < ss; ++sy) {
        for (int sx = 0; sx < ss; ++sx) {
          std::size_t fine = static_cast<std::size_t>(y * ss + sy) * fineW + x * ss + sx;
          std::size_t q = viewPass.hits[fine];
          const ShadingPoint& p = s.point(q);
          float e = lightPass.irradiance[q];
          float value[3];
          for (int k = 0; k < 3; ++k) value[k] = p.albedo[k] * (e + p.occlusion * indirect[k]);
          if (e > 0) {
            const float* n = p.normal;
            float cosL = std::max(n[0] * L[0] + n[1] * L[1] + n[2] * L[2], 1e-4f);
            float cosV = std::max(n[0] * V[0] + n[1] * V[1] + n[2] * V[2], 0.05f);
            float hn = n[0] * H[0] + n[1] * H[1] + n[2] * H[2];
            float gloss = 0, sheen = 0;
            if (p.wardWeight > 0 && hn > 1e-4f) {
              float ht = p.tangent[0] * H[0] + p.tangent[1] * H[1] + p.tangent[2] * H[2];
              float hb = p.bitangent[0] * H[0] + p.bitangent[1] * H[1] + p.bitangent[2] * H[2];
              float exponent = (ht * ht * p.invAlphaT2 + hb * hb * p.invAlphaB2) / (hn * hn);
              // Beyond exp(-40) ~ 4e-18 of its peak the lobe is negligible: skip the exp.
              if (exponent < 40) gloss = p.wardWeight * std::exp(-exponent) * fresnel * e / std::sqrt(cosL * cosV);
            }
            if (p.sheenWeight > 0) {
              float sin2 = std::max(0.0f, 1 - hn * hn);
              // sin^(1/r): the common roughness 0.5 needs no pow.
              float d = p.sheenHalfExponent == 1.0f ? sin2 : std::pow(sin2, p.sheenHalfExponent);
              sheen = p.sheenWeight * d * e / (4 * (cosL + cosV - cosL * cosV));
            }
            for (int k = 0; k < 3; ++k)
              value[k] += gloss + sheen * (1 - traits.sheenTint + traits.sheenTint * p.albedo[k]);
          }
          float m = masked ? viewPass.masking[fine] : 1.0f;
          for (int k = 0; k < 3; ++k) acc[k] += m * value[k];
        }
      }
      float* out = rgb + (static_cast<std::size_t>(y) * impl_->width + x) * 3;
      for (int k = 0; k < 3; ++k) out[k] = acc[k] * scale;
    }
  }
}

}  // namespace nbtf::synth
