#include "codec/nbtf_format.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "codec/zstd_codec.h"
#include "util/half.h"

namespace nbtf {
namespace format {

std::vector<std::uint8_t> bytePlanesOf(const std::vector<std::uint8_t>& records, int width) {
  const std::size_t n = records.size() / width;
  std::vector<std::uint8_t> planes(records.size());
  for (int b = 0; b < width; ++b)
    for (std::size_t i = 0; i < n; ++i) planes[b * n + i] = records[i * width + b];
  return planes;
}
std::vector<std::uint8_t> bytesFromPlanes(const std::vector<std::uint8_t>& planes, int width) {
  const std::size_t n = planes.size() / width;
  std::vector<std::uint8_t> records(planes.size());
  for (int b = 0; b < width; ++b)
    for (std::size_t i = 0; i < n; ++i) records[i * width + b] = planes[b * n + i];
  return records;
}

std::vector<std::uint8_t> toBytePlanes(const std::vector<std::uint32_t>& values, int width) {
  std::vector<std::uint8_t> records(values.size() * width);
  for (std::size_t i = 0; i < values.size(); ++i)
    for (int b = 0; b < width; ++b) records[i * width + b] = static_cast<std::uint8_t>(values[i] >> (8 * b));
  return bytePlanesOf(records, width);
}
std::vector<std::uint32_t> fromBytePlanes(const std::vector<std::uint8_t>& planes, std::size_t n, int width) {
  const std::vector<std::uint8_t> records = bytesFromPlanes(planes, width);
  std::vector<std::uint32_t> values(n, 0);
  for (std::size_t i = 0; i < n; ++i)
    for (int b = 0; b < width; ++b) values[i] |= static_cast<std::uint32_t>(records[i * width + b]) << (8 * b);
  return values;
}

int modulationCodeBytes(int bits) { return bits <= 8 ? 1 : 2; }

std::vector<std::uint8_t> codedIds(const CompressedBtf& btf) {
  auto planes = toBytePlanes(std::vector<std::uint32_t>(btf.ids.begin(), btf.ids.end()), idWidthForClusters(btf.latentRows));
  return zstdCompress(planes.data(), planes.size());
}

std::vector<std::uint8_t> codedModulation(const TexelModulation& m, bool zstd) {
  const int columns = std::max(m.columns(), 1);
  const std::size_t texels = m.codes.size() / columns;
  std::vector<std::uint32_t> byTerm(m.codes.size());
  for (int r = 0; r < columns; ++r)
    for (std::size_t t = 0; t < texels; ++t) byTerm[r * texels + t] = m.codes[t * columns + r];
  const int width = modulationCodeBytes(m.bits);
  if (!zstd || !m.decorrelated) {
    auto planes = toBytePlanes(byTerm, width);
    return zstd ? zstdCompress(planes.data(), planes.size()) : planes;
  }
  // Decorrelated columns differ in spread: a zstd frame each (its own entropy tables), after
  // the frames' sizes (u32 each).
  std::vector<std::uint8_t> out(4 * static_cast<std::size_t>(columns));
  for (int r = 0; r < columns; ++r) {
    const auto planes = toBytePlanes(std::vector<std::uint32_t>(byTerm.begin() + r * texels,
                                                                byTerm.begin() + (r + 1) * texels),
                                     width);
    const auto frame = zstdCompress(planes.data(), planes.size());
    for (int i = 0; i < 4; ++i) out[4 * r + i] = static_cast<std::uint8_t>(frame.size() >> (8 * i));
    out.insert(out.end(), frame.begin(), frame.end());
  }
  return out;
}

// ---- 8-bit decoder weights (DEC8)

float int8RowScale(const float* w, int n) {
  float m = 0;
  for (int i = 0; i < n; ++i) m = std::max(m, std::fabs(w[i]));
  float s = std::max(roundToHalf(m / 127.f), kMinInt8Scale);
  if (m / s > 127.f) s = halfToFloat(static_cast<std::uint16_t>(floatToHalf(s) + 1));  // next half up
  return s;
}
int int8Code(float w, float scale) {
  return static_cast<int>(std::clamp(std::nearbyint(w / scale), -127.f, 127.f));
}

bool storagePlanesHalf(const CompressedBtf& b) { return b.storage.decoderHalf || b.storage.decoderInt8; }

std::vector<float> clusterPlaneRanges(const RowPlanes& planes) {
  const int features = planes.features;
  std::vector<float> ranges(static_cast<std::size_t>(planes.rows) * features * 2);
  for (int row = 0; row < planes.rows; ++row) {
    const float* v = planes.rowValues(row);
    float* r = &ranges[static_cast<std::size_t>(row) * features * 2];
    for (int f = 0; f < features; ++f) r[2 * f] = r[2 * f + 1] = v[f];
    for (std::size_t i = 0; i < planes.valuesPerRow(); ++i) {
      const int f = static_cast<int>(i % features);
      r[2 * f] = std::min(r[2 * f], v[i]);
      r[2 * f + 1] = std::max(r[2 * f + 1], v[i]);
    }
  }
  return ranges;
}
std::uint8_t planeCode(float value, float lo, float hi) {
  if (!(hi > lo)) return 0;
  return static_cast<std::uint8_t>(std::clamp(std::nearbyint((value - lo) / (hi - lo) * 255.f), 0.f, 255.f));
}
float planeCodeValue(int code, float lo, float hi) {
  const float t = static_cast<float>(code) / 255.f;  // 0 and 1 exactly at the ends
  return std::clamp((1 - t) * lo + t * hi, lo, hi);
}

namespace {
// The (lo, hi) pair of value i of `planes` ([row][plane][y][x][feature]) in `ranges`.
const float* rangeOfValue(const RowPlanes& planes, const std::vector<float>& ranges, std::size_t i) {
  return &ranges[(i / planes.valuesPerRow() * planes.features + i % planes.features) * 2];
}
// The values of `planes` after one code-and-decode pass.
std::vector<float> codedValues(const RowPlanes& planes) {
  const std::vector<float> ranges = clusterPlaneRanges(planes);
  return clusterPlaneCodeValues(planes, ranges, clusterPlaneCodes(planes, ranges).data());
}
}  // namespace

std::vector<std::uint8_t> clusterPlaneCodes(const RowPlanes& planes, const std::vector<float>& ranges) {
  std::vector<std::uint8_t> codes(planes.values.size());
  for (std::size_t i = 0; i < codes.size(); ++i) {
    const float* r = rangeOfValue(planes, ranges, i);
    codes[i] = planeCode(planes.values[i], r[0], r[1]);
  }
  return codes;
}
std::vector<float> clusterPlaneCodeValues(const RowPlanes& planes, const std::vector<float>& ranges,
                                          const std::uint8_t* codes) {
  std::vector<float> values(planes.valueCount());
  for (std::size_t i = 0; i < values.size(); ++i) {
    const float* r = rangeOfValue(planes, ranges, i);
    values[i] = planeCodeValue(codes[i], r[0], r[1]);
  }
  return values;
}
void roundClusterPlanesTo8Bit(RowPlanes& planes) {
  // One pass re-codes to itself unless a range spans a few float steps only (then the codes
  // are finer than float); a further pass settles those.
  for (int pass = 0; pass < 4; ++pass) {
    std::vector<float> coded = codedValues(planes);
    if (coded == planes.values) return;
    planes.values = std::move(coded);
  }
}
bool clusterPlanes8BitExact(const RowPlanes& planes) { return codedValues(planes) == planes.values; }

int clusterPlaneBytesPerValue(const CompressedBtf& b) {
  return b.storage.clusterPlanes8Bit ? 1 : storagePlanesHalf(b) ? 2 : 4;
}

}  // namespace format

using format::int8Code;
using format::int8RowScale;
using format::clusterPlaneBytesPerValue;
using format::storagePlanesHalf;

namespace {
const char* valueStorageName(int bytes) { return bytes == 1 ? "8-bit" : bytes == 2 ? "half" : "float32"; }
}  // namespace

std::string storageDescription(const CompressedBtf& btf) {
  if (btf.isPca())
    return std::string("float32 parts, directions ") + (btf.storage.directionsZstd ? "zstd" : "f64") + ", metadata " +
           (btf.storage.metadataZstd ? "zstd" : "raw");
  return std::string("decoder ") + (btf.storage.decoderInt8 ? "int8" : btf.storage.decoderHalf ? "half" : "float32") +
         ", latents " + (btf.storage.latentsHalf ? "half" : "float32") +
         (btf.method == CodecMethod::ClusteredNeural ? std::string(", ids ") + (btf.storage.idsZstd ? "zstd" : "raw")
                                                     : std::string()) +
         (btf.clusterPlanes.empty() ? std::string()
                                    : std::string(", cluster planes ") + valueStorageName(clusterPlaneBytesPerValue(btf))) +
         ", directions " + (btf.storage.directionsZstd ? "zstd" : "f64") + ", metadata " +
         (btf.storage.metadataZstd ? "zstd" : "raw");
}

void roundToStorage(CompressedBtf& btf) {
  if (btf.storage.decoderInt8)
    for (DenseLayer& l : btf.decoder.layers) {
      for (int o = 0; o < l.out; ++o) {
        float* row = l.weight.data() + static_cast<std::size_t>(o) * l.in;
        const float scale = int8RowScale(row, l.in);
        if (!std::isfinite(scale)) continue;  // weights beyond 127 x 65504: the writer refuses them by name
        for (int i = 0; i < l.in; ++i) row[i] = static_cast<float>(int8Code(row[i], scale)) * scale;
      }
      for (float& b : l.bias) b = roundToHalf(b);
    }
  else if (btf.storage.decoderHalf)
    for (DenseLayer& l : btf.decoder.layers) {
      for (float& w : l.weight) w = roundToHalf(w);
      for (float& b : l.bias) b = roundToHalf(b);
    }
  if (btf.storage.latentsHalf && !btf.isPca())
    for (float& z : btf.latents) z = roundToHalf(z);
  if (storagePlanesHalf(btf)) for (float& v : btf.planes.values) v = roundToHalf(v);
  if (clusterPlaneBytesPerValue(btf) == 1)
    format::roundClusterPlanesTo8Bit(btf.clusterPlanes);
  else if (clusterPlaneBytesPerValue(btf) == 2)
    for (float& v : btf.clusterPlanes.values) v = roundToHalf(v);
}

}  // namespace nbtf
