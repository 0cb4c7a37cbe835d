// IEEE-754 binary16 ("half") conversion, round to nearest even, without OpenEXR, so the
// decoding library can read half-precision parts with the standard library alone.
#pragma once
#include <cstdint>
#include <cstddef>
#include <cstring>

namespace nbtf {

inline std::uint16_t floatToHalf(float value) {
  std::uint32_t f;
  std::memcpy(&f, &value, 4);
  const std::uint32_t sign = (f >> 16) & 0x8000u;
  const std::uint32_t exponent = (f >> 23) & 0xFFu;
  std::uint32_t mantissa = f & 0x7FFFFFu;
  if (exponent == 0xFF) return static_cast<std::uint16_t>(sign | 0x7C00u | (mantissa ? 0x200u : 0));  // Inf, NaN
  int e = static_cast<int>(exponent) - 127 + 15;
  if (e >= 31) return static_cast<std::uint16_t>(sign | 0x7C00u);  // overflow -> infinity
  if (e <= 0) {
    // Subnormal half (or zero): shift the full mantissa, round to nearest even.
    if (e < -10) return static_cast<std::uint16_t>(sign);
    mantissa |= 0x800000u;
    const int shift = 14 - e;
    std::uint32_t half = mantissa >> shift;
    const std::uint32_t rest = mantissa & ((1u << shift) - 1), halfway = 1u << (shift - 1);
    if (rest > halfway || (rest == halfway && (half & 1u))) ++half;
    return static_cast<std::uint16_t>(sign | half);
  }
  std::uint32_t half = (static_cast<std::uint32_t>(e) << 10) | (mantissa >> 13);
  const std::uint32_t rest = mantissa & 0x1FFFu;
  if (rest > 0x1000u || (rest == 0x1000u && (half & 1u))) ++half;  // may carry into the exponent: correct
  return static_cast<std::uint16_t>(sign | half);
}

inline float halfToFloat(std::uint16_t h) {
  const std::uint32_t sign = static_cast<std::uint32_t>(h & 0x8000u) << 16;
  std::uint32_t exponent = (h >> 10) & 0x1Fu, mantissa = h & 0x3FFu, f;
  if (exponent == 0x1F) {
    f = sign | 0x7F800000u | (mantissa << 13);
  } else if (exponent == 0) {
    if (mantissa == 0) {
      f = sign;
    } else {  // subnormal: normalize
      int e = -1;
      do {
        ++e;
        mantissa <<= 1;
      } while (!(mantissa & 0x400u));
      f = sign | (static_cast<std::uint32_t>(127 - 15 - e) << 23) | ((mantissa & 0x3FFu) << 13);
    }
  } else {
    f = sign | ((exponent + 127 - 15) << 23) | (mantissa << 13);
  }
  float out;
  std::memcpy(&out, &f, 4);
  return out;
}

// The nearest half-precision value, as a float (what storing and reading back gives):
// halfToFloat(floatToHalf(v)) bit for bit, but without branches, so that a loop over many
// values vectorizes. Normal halves: round the float's mantissa to 10 bits (to nearest even;
// a carry moves into the exponent, as it should). Subnormal ones (|v| < 2^-14): adding 0.5
// rounds |v| to a multiple of 2^-24, the float spacing there and the half one.
inline float roundToHalf(float v) {
  std::uint32_t f, sub;
  std::memcpy(&f, &v, 4);
  const std::uint32_t sign = f & 0x80000000u, a = f ^ sign;
  float magnitude;
  std::memcpy(&magnitude, &a, 4);
  const float subnormal = (magnitude + 0.5f) - 0.5f;
  std::memcpy(&sub, &subnormal, 4);
  const std::uint32_t normal = (a + 0xFFFu + ((a >> 13) & 1u)) & 0xFFFFE000u;
  std::uint32_t r = a < 0x38800000u   ? sub                          // below 2^-14
                    : a < 0x477FF000u ? normal                       // below 65520
                    : a <= 0x7F800000u ? 0x7F800000u : 0x7FC00000u;  // infinity, NaN (quiet)
  r |= sign;
  float out;
  std::memcpy(&out, &r, 4);
  return out;
}

// roundToHalf(max(0, v)) on n values in place: a reflectance stored as a half and read back.
// Four at a time in GCC vector types (the scalar loop does not vectorize); the clamped value
// is never negative or NaN, so roundToHalf's sign and NaN cases drop out and its unsigned
// comparisons become signed ones. The same bits as the scalar form (test in half_test.cpp).
inline void roundToHalfClampedAtZero(float* v, std::size_t n) {
  typedef float Floats __attribute__((vector_size(16)));
  typedef std::int32_t Ints __attribute__((vector_size(16)));
  std::size_t i = 0;
  for (; i + 4 <= n; i += 4) {
    Floats x;
    std::memcpy(&x, v + i, sizeof x);
    x = x > 0.0f ? x : Floats{};  // max(0, x), NaN included
    const Floats subnormal = (x + 0.5f) - 0.5f;
    Ints a, sub;
    std::memcpy(&a, &x, sizeof a);
    std::memcpy(&sub, &subnormal, sizeof sub);
    const Ints normal = (a + 0xFFF + ((a >> 13) & 1)) & ~0x1FFF;
    Ints r = a < 0x38800000 ? sub : normal;
    r = a < 0x477FF000 ? r : Ints{} + 0x7F800000;
    std::memcpy(v + i, &r, sizeof r);
  }
  for (; i < n; ++i) v[i] = roundToHalf(v[i] > 0.0f ? v[i] : 0.0f);
}

}  // namespace nbtf
