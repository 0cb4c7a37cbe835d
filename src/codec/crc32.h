// CRC-32 (IEEE 802.3 polynomial, reflected; the same value as zlib's crc32() and PNG),
// used by the .nbtf file to detect corruption. Own implementation: no zlib dependency.
#pragma once
#include <cstddef>
#include <cstdint>

namespace nbtf {

// Continues a running CRC: crc32(crc32(0, a), b) == crc32(0, a + b).
std::uint32_t crc32(std::uint32_t crc, const void* data, std::size_t size);
inline std::uint32_t crc32(const void* data, std::size_t size) { return crc32(0, data, size); }

}  // namespace nbtf
