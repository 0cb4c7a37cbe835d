// Colour conversions: sRGB transfer function and CIE XYZ (D65) -> linear sRGB.
#pragma once
#include <cstdint>

namespace nbtf {

// sRGB-encoded 8-bit value -> linear [0, 1] (exact IEC 61966-2-1 curve, table lookup).
float srgb8ToLinear(std::uint8_t v);
const float* srgb8ToLinearTable();  // 256 entries
float srgbEncode(float linear);     // linear -> sRGB-encoded [0, 1] (clamped)
std::uint8_t linearToSrgb8(float linear);

// CIE XYZ (D65 white) -> linear sRGB (Rec. 709 primaries). In place on one RGB triple.
void xyzToLinearSrgb(float* xyz);
void linearSrgbToXyz(float* rgb);

}  // namespace nbtf
