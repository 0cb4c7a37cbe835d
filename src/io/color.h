// Colour conversions: sRGB transfer function (and its fast exact 8-bit encoder) and CIE XYZ
// (D65) -> linear sRGB.
#pragma once
#include <cstdint>
#include <cstring>
#include <vector>

namespace nbtf {

// sRGB-encoded 8-bit value -> linear [0, 1] (exact IEC 61966-2-1 curve, table lookup).
float srgb8ToLinear(std::uint8_t v);
const float* srgb8ToLinearTable();  // 256 entries
float srgbEncode(float linear);     // linear -> sRGB-encoded [0, 1] (clamped)
std::uint8_t linearToSrgb8(float linear);

// CIE XYZ (D65 white) -> linear sRGB (Rec. 709 primaries). In place on one RGB triple.
void xyzToLinearSrgb(float* xyz);
void linearSrgbToXyz(float* rgb);

// linearToSrgb8, bit-exact, without a pow() per value: a table indexed by the
// float's bit pattern gives the code at the start of the value's bucket (2^13 neighbouring
// floats, a relative width of 1e-3, narrower than any gap between two rounding thresholds),
// and one comparison with the next threshold finishes it. Modulated materials encode every
// texel of every decoded image (65.6 million values for a 100 x 100 x 6561 stack), so this
// is on the decoder's critical path.
class Srgb8Encoder {
 public:
  Srgb8Encoder();
  std::uint8_t operator()(float linear) const {
    if (!(linear > 0)) return 0;  // also NaN, like linearToSrgb8
    if (linear >= 1.0f) return 255;
    std::uint32_t bits;
    std::memcpy(&bits, &linear, sizeof bits);
    if (bits < firstBits_) return 0;
    const int code = bucketCode_[(bits - firstBits_) >> kBucketShift];
    return static_cast<std::uint8_t>(code + (linear >= thresholds_[code]));
  }

 private:
  static constexpr int kBucketShift = 13;
  float thresholds_[256];                  // smallest linear value that encodes to i + 1; [255] = +inf
  std::uint32_t firstBits_ = 0;            // bit pattern of thresholds_[0]
  std::vector<std::uint8_t> bucketCode_;  // code of each bucket's first float
};
// The one encoder every writer shares (its tables are built on first use).
const Srgb8Encoder& srgb8Encoder();

}  // namespace nbtf
