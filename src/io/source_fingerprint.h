// A small fingerprint of the stack a file was made from (META JSON, "source"."fingerprint"):
// the mean linear RGB of evenly spaced images over the texels compressed, and the pattern of
// the texels: the median luminance over those images at a grid of up to 16 x 16 texels, in 8
// bits between its minimum and maximum (about 300 bytes in the file). `nbtf eval` checks its
// reference against it, so a report against the wrong material cannot pass silently: the
// means tell materials apart, the pattern tells apart two captures of one kind of material
// (two pieces of the same fabric have the same means, not the same threads in the same place).
#pragma once
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "io/btf_stack.h"

namespace nbtf {

struct SourceFingerprint {
  std::vector<int> images;                     // image indices (light * views + view)
  std::vector<std::array<double, 3>> meanRgb;  // per image: mean linear RGB over the texels
  // The texel pattern (empty in files made before it was recorded): gridX x gridY texels,
  // texel (i, j) at x = (2i + 1) * width / (2 gridX) (likewise y), row-major; each the median
  // linear luminance over `images`, coded in 8 bits from patternMin to patternMax.
  int gridX = 0, gridY = 0;
  double patternMin = 0, patternMax = 0;
  std::vector<std::uint8_t> pattern;
};

// Up to `maxImages` evenly spaced images of the stack (as loaded: crop applied).
SourceFingerprint sourceFingerprint(const BtfStack& stack, int maxImages = 32);
// The JSON object stored under "source"."fingerprint".
std::string sourceFingerprintJson(const SourceFingerprint& fp);
// The fingerprint in a file's META JSON; nullopt when the file has none (older files).
// Throws nbtf::Error naming `fileName` when it is present but malformed.
std::optional<SourceFingerprint> sourceFingerprintOf(const std::string& metadataJson, const std::string& fileName);

// Per image and channel, the relative difference |a - b| / (max(a, b) + 1% of the brightest
// mean); the reference matches when the median is within `tolerance`. The median survives
// 8-bit vs float loading (quantization, clipped highlights in a few images); another
// material differs in most images.
struct FingerprintCheck {
  bool matches = true;
  double medianDifference = 0;  // relative
  // The texel pattern: RMS difference of the sampled luminances over their standard deviation
  // in the stored pattern. Measured on nbtf-synth's five presets (24 x 24, JPEG stacks): the
  // capture itself 0.004-0.014, the same preset with another seed 0.43-1.30. -1 when not
  // compared (an older file, or a uniform material, which has no pattern).
  double patternDifference = -1;
  bool patternMatches = true;
  int worstImage = -1;          // image index with the largest difference
  std::array<double, 3> stored{}, measured{};  // that image's means
};
// The pattern matches when its difference is at most `patternTolerance`.
FingerprintCheck checkSourceFingerprint(const SourceFingerprint& stored, const BtfStack& reference,
                                        double tolerance = 0.1, double patternTolerance = 0.1);

}  // namespace nbtf
