// Synthetic BTF materials: a meso-structured surface rendered under any light/view pair,
// written in the UBO2003 or UTIA layout with its exact linear float ground truth.
//
// Model (docs/data_tools.md has the details): a tileable height field with woven, knit,
// pile or grain structure, sampled supersampling^2 times per texel; per sample a
// Lambertian albedo, an anisotropic Ward lobe along the fibre direction and an optional
// cloth sheen lobe; soft self-shadowing by marching the height field toward the light;
// parallax and masking by marching the view ray (or masking only, without parallax); a
// one-bounce interreflection estimate. A distant light of unit irradiance at normal
// incidence and an orthographic camera, as in a BTF measurement.
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "io/btf_stack.h"
#include "util/directions.h"
#include "io/image_io.h"

namespace nbtf::synth {

std::vector<std::string> presetNames();
std::string presetDescription(const std::string& preset);  // throws nbtf::Error on an unknown preset

// Sizes the generator accepts, per axis (texels).
constexpr int kMinSize = 8, kMaxSize = 1024;

struct RenderSettings {
  bool parallax = true;         // look up the texel seen along the view ray; false: the texel below, masked
  bool shadows = true;          // self-shadowing toward the light
  bool interreflection = true;  // one-bounce indirect light in occluded places
  int supersampling = 2;        // fine samples per texel along each axis (1..4)
};

// A material is deterministic for (preset, width, height, seed, settings), on any thread count.
class SynthMaterial {
 public:
  SynthMaterial(const std::string& preset, int width, int height, std::uint64_t seed);
  SynthMaterial(const std::string& preset, int width, int height, std::uint64_t seed, const RenderSettings& settings);
  ~SynthMaterial();
  SynthMaterial(SynthMaterial&&) noexcept;
  int width() const;
  int height() const;
  const std::string& preset() const;
  const RenderSettings& settings() const;
  // Linear RGB of every texel (width * height * 3 floats, row-major) for one light/view pair.
  void render(const Direction& light, const Direction& view, float* rgb) const;

  // Batch rendering: the light-dependent part (shadowing) and the view-dependent part
  // (parallax, masking) of render() prepared once and shared by every pair that uses
  // them. render(prepareLight(l), prepareView(v)) equals render(l, v) exactly.
  struct LightPass;
  struct ViewPass;
  std::shared_ptr<const LightPass> prepareLight(const Direction& light) const;
  std::shared_ptr<const ViewPass> prepareView(const Direction& view) const;
  void render(const LightPass& light, const ViewPass& view, float* rgb) const;

  // The meso-structure's height per texel (mean of its fine samples, texels), row-major:
  // for previews and tests.
  std::vector<float> heightMap() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct SynthOptions {
  std::string preset = "fabric";
  int width = 64, height = 64;
  std::uint64_t seed = 1;
  Layout layout = Layout::Ubo2003;
  ImageFormat format = ImageFormat::Jpg;  // ubo2003: jpg; utia: png or exr
  RenderSettings render;
  bool groundTruth = true;  // DIR/ground_truth/<view folder>.exr, float32, lights stacked vertically
  bool progress = true;
};

// Checks the options (preset, size, layout/format pairing, supersampling); throws
// nbtf::Error saying what is wrong.
void validateSynthOptions(const SynthOptions& options);

// What writeSynthStack wrote, measured on the linear float values.
struct SynthSummary {
  int images = 0;            // stack images written
  int groundTruthFiles = 0;  // ground-truth EXRs written
  float minValue = 0, maxValue = 0;  // linear sRGB, over every texel, channel and image
  double meanValue = 0;              // linear sRGB
  double clippedFraction = 0;        // fraction of samples above 1 (clipped in 8-bit files)
  double seconds = 0;
};

// Writes the stack into outDir (created if needed) plus outDir/synth.json describing it.
// outDir must be empty or hold an earlier nbtf-synth output (whose files are replaced;
// nothing else is ever deleted).
SynthSummary writeSynthStack(const SynthOptions& options, const std::string& outDir);

// Reads image (light index, view index) of a written ground truth, linear float RGB
// (width * height * 3, row-major). Indices follow hemisphere81().
std::vector<float> readGroundTruthImage(const std::string& outDir, int light, int view);

}  // namespace nbtf::synth
