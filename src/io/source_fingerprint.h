// A small fingerprint of the stack a file was made from (META JSON, "source"."fingerprint"):
// the mean linear RGB of evenly spaced images over the texels compressed. `nbtf eval` checks
// its reference against it, so a report against the wrong material cannot pass silently.
#pragma once
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "io/btf_stack.h"

namespace nbtf {

struct SourceFingerprint {
  std::vector<int> images;                     // image indices (light * views + view)
  std::vector<std::array<double, 3>> meanRgb;  // per image: mean linear RGB over the texels
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
  int worstImage = -1;          // image index with the largest difference
  std::array<double, 3> stored{}, measured{};  // that image's means
};
FingerprintCheck checkSourceFingerprint(const SourceFingerprint& stored, const BtfStack& reference,
                                        double tolerance = 0.1);

}  // namespace nbtf
