// Internals of the .nbtf format shared by its reader, writer, size table and validation
// (codec/nbtf_*.cpp): the framing constants, the limits, and how the compact parts are coded.
// Not part of the decoder's interface; docs/file_format.md describes the bytes.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "codec/nbtf_file.h"

namespace nbtf::format {

// Layout (docs/file_format.md).
constexpr std::size_t kHeaderSize = 32;
constexpr std::size_t kHeaderCrcOffset = 28;  // header CRC covers bytes [0, 28)
constexpr std::size_t kSectionHeaderSize = 24;
constexpr std::size_t kAlign = 8;             // payloads are zero-padded to a multiple of 8
constexpr std::uint32_t kSectionRequired = 1; // a reader that does not know the tag must refuse

// Limits that keep every derived size far from overflow; real materials are far below.
constexpr std::uint32_t kMaxSide = 1u << 20;
constexpr std::uint32_t kMaxLatentDim = 4096;
constexpr std::uint32_t kMaxPcaComponents = 1u << 16;
constexpr std::uint32_t kMaxLayers = 256;
constexpr std::uint32_t kMaxLayerWidth = 1u << 16;
constexpr int kMaxJsonDepth = 64;
constexpr std::uint32_t kMaxMetadataBytes = 64u << 20;  // METZ: bounds the allocation a hostile size asks for
constexpr std::uint64_t kMaxDirections = 1u << 20;      // DIRZ: lights or views (bounds the frame's size)
constexpr float kMaxModulationMagnitude = 1e6f;  // coefficient ranges: no overflow in products

inline bool allFinite(const std::vector<float>& v) {
  return std::all_of(v.begin(), v.end(), [](float x) { return std::isfinite(x); });
}

// ---- Coded parts (format 1.2), shared by the writer, the reader and computeSizes

// Records of `width` bytes as byte planes (byte 0 of every record, then byte 1...), and back:
// neighbouring texels share clusters and codes, and the planes put the repetitive bytes
// together for zstd.
std::vector<std::uint8_t> bytePlanesOf(const std::vector<std::uint8_t>& records, int width);
std::vector<std::uint8_t> bytesFromPlanes(const std::vector<std::uint8_t>& planes, int width);
// Integers of `width` bytes (little-endian) as byte planes, and back.
std::vector<std::uint8_t> toBytePlanes(const std::vector<std::uint32_t>& values, int width);
std::vector<std::uint32_t> fromBytePlanes(const std::vector<std::uint8_t>& planes, std::size_t n, int width);

int modulationCodeBytes(int bits);  // 1 up to 8 bits, else 2
// The id list as TXIZ stores it: a zstd frame of the ids' byte planes.
std::vector<std::uint8_t> codedIds(const CompressedBtf& btf);
// The modulation codes column by column (all texels' column 0, then column 1...), as byte
// planes, zstd-coded when `zstd`.
std::vector<std::uint8_t> codedModulation(const TexelModulation& m, bool zstd);

// ---- 8-bit decoder weights (DEC8)

// The smallest normal half value 2^-14: a row's scale is never below it, so a row of tiny
// weights keeps codes below 127 and still re-quantizes to itself.
constexpr float kMinInt8Scale = 6.103515625e-05f;
// Scale of one output row: the smallest half value s >= 2^-14 with max|w| / s <= 127. Then
// the row's largest weight is code +-127 (unless the scale is the minimum), and quantizing
// q x s again gives the same scale and codes: the writer re-derives them from the values.
float int8RowScale(const float* w, int n);
int int8Code(float w, float scale);

// Direction planes follow the decoder's storage: float32 with a float32 decoder, half otherwise.
bool storagePlanesHalf(const CompressedBtf& b);

// ---- 8-bit cluster planes (CPLN value type 2, format 1.10)

// Bytes per stored cluster plane value: 1 (8-bit codes), 2 (half, beside a half or 8-bit
// decoder) or 4 (float32).
int clusterPlaneBytesPerValue(const CompressedBtf& b);

// Each row's feature f spans [lo, hi] (float32, the extremes of its values over the row's three
// planes); a value is stored as the code round(255 (v - lo) / (hi - lo)). Codes 0 and 255 decode
// to lo and hi exactly, so the ranges of decoded values are the stored ones: the writer
// re-derives ranges and codes from the values in memory, as with DEC8.
// The ranges of `planes`: rows x features pairs (lo, hi), row-major.
std::vector<float> clusterPlaneRanges(const RowPlanes& planes);
std::uint8_t planeCode(float value, float lo, float hi);
float planeCodeValue(int code, float lo, float hi);
// The code of each value of `planes` in its range, and the values codes decode to (`planes`
// gives the shape only).
std::vector<std::uint8_t> clusterPlaneCodes(const RowPlanes& planes, const std::vector<float>& ranges);
std::vector<float> clusterPlaneCodeValues(const RowPlanes& planes, const std::vector<float>& ranges,
                                          const std::uint8_t* codes);
// planes.values replaced by their 8-bit decoded values.
void roundClusterPlanesTo8Bit(RowPlanes& planes);
// Whether the values are 8-bit decoded values already (the writer stores them exactly).
bool clusterPlanes8BitExact(const RowPlanes& planes);

}  // namespace nbtf::format
