#include "codec/zstd_codec.h"

#include <zstd.h>

#include "util/error.h"

namespace nbtf {

std::vector<std::uint8_t> zstdCompress(const std::uint8_t* data, std::size_t size, int level) {
  std::vector<std::uint8_t> out(ZSTD_compressBound(size));
  const std::size_t n = ZSTD_compress(out.data(), out.size(), data, size, level);
  if (ZSTD_isError(n)) throw Error(std::string("zstd compression failed: ") + ZSTD_getErrorName(n));
  out.resize(n);
  return out;
}

std::vector<std::uint8_t> zstdDecompress(const std::uint8_t* data, std::size_t size, std::size_t expectedSize,
                                         const std::string& file, const std::string& what) {
  const unsigned long long declared = ZSTD_getFrameContentSize(data, size);
  if (declared == ZSTD_CONTENTSIZE_ERROR || declared == ZSTD_CONTENTSIZE_UNKNOWN)
    throw fileError(file, what + ": not a zstd frame with a declared size (corrupted)");
  if (declared != expectedSize)
    throw fileError(file, what + ": the compressed data declares " + std::to_string(declared) + " bytes, expected " +
                              std::to_string(expectedSize));
  const std::size_t frame = ZSTD_findFrameCompressedSize(data, size);
  if (ZSTD_isError(frame)) throw fileError(file, what + ": damaged zstd frame (" + ZSTD_getErrorName(frame) + ")");
  if (frame != size)
    throw fileError(file, what + ": " + std::to_string(size - frame) + " unexpected bytes after the zstd frame");
  std::vector<std::uint8_t> out(expectedSize);
  const std::size_t n = ZSTD_decompress(out.data(), out.size(), data, size);
  if (ZSTD_isError(n)) throw fileError(file, what + ": damaged zstd data (" + ZSTD_getErrorName(n) + ")");
  if (n != expectedSize)
    throw fileError(file, what + ": decompressed to " + std::to_string(n) + " bytes, expected " +
                              std::to_string(expectedSize));
  return out;
}

}  // namespace nbtf
