#include "io/color.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

#include "util/error.h"

namespace nbtf {
namespace {
float decode(float s) { return s <= 0.04045f ? s / 12.92f : std::pow((s + 0.055f) / 1.055f, 2.4f); }
}  // namespace

const float* srgb8ToLinearTable() {
  static const std::array<float, 256> table = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i) t[i] = decode(i / 255.0f);
    return t;
  }();
  return table.data();
}

float srgb8ToLinear(std::uint8_t v) { return srgb8ToLinearTable()[v]; }

float srgbEncode(float linear) {
  if (!(linear > 0)) return 0;
  if (linear >= 1) return 1;
  return linear <= 0.0031308f ? 12.92f * linear : 1.055f * std::pow(linear, 1 / 2.4f) - 0.055f;
}

std::uint8_t linearToSrgb8(float linear) {
  return static_cast<std::uint8_t>(std::lround(srgbEncode(linear) * 255.0f));
}

void xyzToLinearSrgb(float* c) {
  float x = c[0], y = c[1], z = c[2];
  c[0] = 3.2404542f * x - 1.5371385f * y - 0.4985314f * z;
  c[1] = -0.9692660f * x + 1.8760108f * y + 0.0415560f * z;
  c[2] = 0.0556434f * x - 0.2040259f * y + 1.0572252f * z;
}

void linearSrgbToXyz(float* c) {
  float r = c[0], g = c[1], b = c[2];
  c[0] = 0.4124564f * r + 0.3575761f * g + 0.1804375f * b;
  c[1] = 0.2126729f * r + 0.7151522f * g + 0.0721750f * b;
  c[2] = 0.0193339f * r + 0.1191920f * g + 0.9503041f * b;
}

namespace {
float floatFromBits(std::uint32_t b) {
  float f;
  std::memcpy(&f, &b, sizeof f);
  return f;
}
std::uint32_t bitsOf(float f) {
  std::uint32_t b;
  std::memcpy(&b, &f, sizeof b);
  return b;
}
}  // namespace

Srgb8Encoder::Srgb8Encoder() {
  // Non-negative floats order like their bit patterns: bisect on the bits.
  for (int i = 0; i < 255; ++i) {
    std::uint32_t lo = 0, hi = bitsOf(1.0f);
    while (lo < hi) {
      std::uint32_t mid = lo + (hi - lo) / 2;
      if (linearToSrgb8(floatFromBits(mid)) >= i + 1) hi = mid;
      else lo = mid + 1;
    }
    thresholds_[i] = floatFromBits(lo);
  }
  thresholds_[255] = INFINITY;
  auto codeOf = [this](float x) {  // the number of thresholds <= x
    return static_cast<int>(std::upper_bound(thresholds_, thresholds_ + 255, x) - thresholds_);
  };
  firstBits_ = bitsOf(thresholds_[0]);
  const std::uint32_t buckets = ((bitsOf(1.0f) - firstBits_) >> kBucketShift) + 1;
  bucketCode_.resize(buckets);
  for (std::uint32_t b = 0; b < buckets; ++b) {
    const std::uint32_t first = firstBits_ + (b << kBucketShift), last = first + (1u << kBucketShift) - 1;
    bucketCode_[b] = static_cast<std::uint8_t>(codeOf(floatFromBits(first)));
    // One comparison finishes a value only if its bucket holds at most one threshold.
    if (codeOf(floatFromBits(std::min(last, bitsOf(1.0f)))) > bucketCode_[b] + 1)
      throw Error("Srgb8Encoder: two sRGB rounding thresholds in one table bucket");
  }
}

const Srgb8Encoder& srgb8Encoder() {
  static const Srgb8Encoder encoder;
  return encoder;
}

}  // namespace nbtf
