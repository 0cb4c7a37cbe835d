// Synthetic BTF materials: a meso-structured surface rendered under any light/view pair,
// written in the UBO2003 or UTIA layout with its exact linear float ground truth.
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "io/btf_stack.h"
#include "io/directions.h"
#include "io/image_io.h"

namespace nbtf::synth {

std::vector<std::string> presetNames();
std::string presetDescription(const std::string& preset);

// A material is deterministic for (preset, width, height, seed).
class SynthMaterial {
 public:
  SynthMaterial(const std::string& preset, int width, int height, std::uint64_t seed);
  ~SynthMaterial();
  SynthMaterial(SynthMaterial&&) noexcept;
  int width() const;
  int height() const;
  // Linear RGB of every texel (width * height * 3 floats, row-major) for one light/view pair.
  void render(const Direction& light, const Direction& view, float* rgb) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct SynthOptions {
  std::string preset = "fabric";
  int width = 64, height = 64;
  std::uint64_t seed = 1;
  Layout layout = Layout::Ubo2003;
  ImageFormat format = ImageFormat::Jpg;
  bool groundTruth = true;  // DIR/ground_truth/<view folder>.exr, float32, lights stacked vertically
  bool progress = true;
};

// Writes the stack into outDir (created if needed) plus outDir/synth.json describing it.
void writeSynthStack(const SynthOptions& options, const std::string& outDir);

// Reads image (light index, view index) of a written ground truth, linear float RGB.
std::vector<float> readGroundTruthImage(const std::string& outDir, int light, int view);

}  // namespace nbtf::synth
