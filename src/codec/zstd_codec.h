// Lossless byte compression for the parts of a `.nbtf` that are entropy-coded (the id list,
// the per-texel scale codes). zstd from Debian (libzstd); deterministic for a level.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace nbtf {

// Compresses `size` bytes into one zstd frame (single-threaded, so the same input always
// gives the same bytes).
std::vector<std::uint8_t> zstdCompress(const std::uint8_t* data, std::size_t size, int level = 19);

// Decompresses one frame that must hold exactly `expectedSize` bytes. Untrusted input: a
// frame that is damaged, declares another size, or has trailing bytes throws nbtf::Error
// naming `file` and `what`; never allocates more than expectedSize.
std::vector<std::uint8_t> zstdDecompress(const std::uint8_t* data, std::size_t size, std::size_t expectedSize,
                                         const std::string& file, const std::string& what);

}  // namespace nbtf
