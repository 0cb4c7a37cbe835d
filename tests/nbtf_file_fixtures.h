// Shared by the nbtf_*_test.cpp format tests: compact-format materials and edits of serialized .nbtf bytes.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "codec/crc32.h"
#include "codec/nbtf_file.h"
#include "codec/texel_modulation.h"
#include "codec_fixtures.h"
#include "decoder_fixtures.h"
#include "util/byte_io.h"
#include "util/error.h"

namespace nbtf {

// A decoder for `terms` modulation terms: makeBtf's, with 3 x terms outputs.
inline void setTerms(CompressedBtf& b, int terms) {
  DenseLayer& last = b.decoder.layers.back();
  last.out = 3 * terms;
  last.weight.assign(static_cast<std::size_t>(last.in) * last.out, 0.125f);
  last.bias.assign(last.out, -0.5f);
}

// A format-1.2 file: per-texel modulation (3 terms, 6-bit codes), half-precision decoder
// and latents, zstd-coded ids.
inline CompressedBtf makeCompactBtf(int k = 5, int terms = 3, int bits = 6, int channels = 1) {
  CompressedBtf b = testing::makeBtf(k);
  std::vector<float> coefficients(static_cast<std::size_t>(b.numTexels()) * terms * channels);
  for (std::size_t i = 0; i < coefficients.size(); ++i) coefficients[i] = 0.5f - 0.11f * static_cast<float>(i % 9);
  b.modulation = quantizeTexelCoefficients(coefficients, terms, bits, channels);
  setTerms(b, terms);
  b.storage.decoderHalf = b.storage.latentsHalf = b.storage.idsZstd = true;
  roundToStorage(b);
  return b;
}

// A format-1.11 file: per-channel coefficients in decorrelated codes (two terms).
inline CompressedBtf makeDecorrelatedBtf() {
  CompressedBtf b = testing::makeBtf(5);
  std::vector<float> coefficients(static_cast<std::size_t>(b.numTexels()) * 6);
  for (std::size_t i = 0; i < coefficients.size(); ++i)
    coefficients[i] = 1.0f + 0.1f * static_cast<float>(i / 6 % 7) * (1 + i % 3) - 0.03f * static_cast<float>(i % 5);
  b.modulation = quantizeTexelCoefficients(coefficients, 2, 6, 3, ModulationCodes::Decorrelated);
  setTerms(b, 2);
  b.storage.idsZstd = true;
  return b;
}

// A format-1.10 file: direction planes, and cluster planes in 8 bits.
inline CompressedBtf makeClusterPlanes8BitBtf() {
  CompressedBtf b =
      testing::makeDecoderMaterial(5, {37, 21}, 7, 5, 11, DirectionEncoding::StereographicFourier2, 2, 2);
  b.storage.decoderInt8 = b.storage.clusterPlanes8Bit = true;
  roundToStorage(b);
  return b;
}

inline std::string errorOf(const std::vector<std::uint8_t>& bytes, std::size_t size = SIZE_MAX,
                           NbtfParseOptions options = {}) {
  try {
    parseNbtf(bytes.data(), std::min(size, bytes.size()), "mat.nbtf", options);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

inline bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

// Recomputes the declared size and both CRCs after a test edited the bytes on purpose.
inline void resealHeader(std::vector<std::uint8_t>& b) {
  ByteWriter w;
  w.bytes() = b;
  w.patchU64(16, b.size());
  w.patchU32(24, crc32(b.data() + 32, b.size() - 32));
  w.patchU32(28, crc32(w.bytes().data(), 28));
  b = w.bytes();
}

inline void appendSection(std::vector<std::uint8_t>& b, const char* tag, std::uint32_t flags,
                          const std::vector<std::uint8_t>& payload, std::uint64_t declaredSize = UINT64_MAX) {
  ByteWriter w;
  w.raw(tag, 4);
  w.u32(flags);
  w.u64(declaredSize == UINT64_MAX ? payload.size() : declaredSize);
  w.u32(crc32(payload.data(), payload.size()));
  w.u32(0);
  w.raw(payload.data(), payload.size());
  w.zeros((8 - payload.size() % 8) % 8);
  b.insert(b.end(), w.bytes().begin(), w.bytes().end());
  resealHeader(b);
}

// Offset of a section's header in a serialized file.
inline std::size_t findSection(const std::vector<std::uint8_t>& b, const char* tag) {
  std::size_t pos = 32;
  while (pos + 24 <= b.size()) {
    std::uint64_t size = 0;
    for (int i = 0; i < 8; ++i) size |= std::uint64_t(b[pos + 8 + i]) << (8 * i);
    if (std::memcmp(&b[pos], tag, 4) == 0) return pos;
    pos += 24 + size + (8 - size % 8) % 8;
  }
  return 0;
}

inline void putU32(std::vector<std::uint8_t>& b, std::size_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) b[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
}

// Rewrites a section's stored CRC after its payload was edited on purpose.
inline void resealSection(std::vector<std::uint8_t>& b, std::size_t sectionOffset) {
  std::uint64_t size = 0;
  for (int i = 0; i < 8; ++i) size |= std::uint64_t(b[sectionOffset + 8 + i]) << (8 * i);
  putU32(b, sectionOffset + 16, crc32(&b[sectionOffset + 24], size));
  resealHeader(b);
}

}  // namespace nbtf
