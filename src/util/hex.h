// Bytes as lowercase hexadecimal text ("0a1f"), and back: for small binary values kept in
// JSON or printed (a fingerprint's pattern, a generated secret).
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace nbtf {

inline std::string toHex(const std::uint8_t* data, std::size_t size) {
  static const char digits[] = "0123456789abcdef";
  std::string text;
  text.reserve(2 * size);
  for (std::size_t i = 0; i < size; ++i) text += digits[data[i] >> 4], text += digits[data[i] & 15];
  return text;
}

// False, with `out` unspecified, when the text has an odd length or a character that is not a
// lowercase hexadecimal digit.
inline bool fromHex(const std::string& text, std::vector<std::uint8_t>& out) {
  auto digit = [](char c) { return c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10 : -1; };
  if (text.size() % 2 != 0) return false;
  out.clear();
  for (std::size_t i = 0; i < text.size(); i += 2) {
    const int hi = digit(text[i]), lo = digit(text[i + 1]);
    if (hi < 0 || lo < 0) return false;
    out.push_back(static_cast<std::uint8_t>(16 * hi + lo));
  }
  return true;
}

}  // namespace nbtf
