// Text for people: bytes from a file quoted in an error message, numbers with their digits
// grouped.
//
// Bytes from a file, quoted in an error message: printable ASCII as is, anything else as
// \xNN, so a binary signature or tag never garbles the terminal.
#pragma once
#include <cstddef>
#include <cstdio>
#include <string>

namespace nbtf {

inline std::string printableBytes(const void* data, std::size_t size) {
  const auto* p = static_cast<const unsigned char*>(data);
  std::string out;
  for (std::size_t i = 0; i < size; ++i) {
    if (p[i] >= 0x20 && p[i] < 0x7F) {
      out += static_cast<char>(p[i]);
    } else {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02X", p[i]);
      out += hex;
    }
  }
  return out;
}

// 24383 -> "24,383".
inline std::string groupedDigits(unsigned long long v) {
  const std::string digits = std::to_string(v);
  std::string out;
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}

}  // namespace nbtf
