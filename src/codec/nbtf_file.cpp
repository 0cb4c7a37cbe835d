#include "codec/nbtf_file.h"

#include <algorithm>
#include <cinttypes>
#include <climits>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>

#include "util/byte_io.h"
#include "codec/crc32.h"
#include "codec/zstd_codec.h"
#include "util/half.h"
#include "util/atomic_file.h"
#include "util/error.h"
#include "util/printable.h"

namespace nbtf {
namespace {

// ---- Layout constants (docs/file_format.md)

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

constexpr std::uint32_t tag(const char (&s)[5]) {
  return std::uint32_t(std::uint8_t(s[0])) | std::uint32_t(std::uint8_t(s[1])) << 8 |
         std::uint32_t(std::uint8_t(s[2])) << 16 | std::uint32_t(std::uint8_t(s[3])) << 24;
}
constexpr std::uint32_t kInfo = tag("INFO"), kDirs = tag("DIRS"), kDecoder = tag("DECD"), kLatents = tag("LATN"),
                        kIds = tag("TXID"), kHoldout = tag("HOLD"), kEncoder = tag("ENCD"), kMeta = tag("META"),
                        kPcaMean = tag("PCAM"), kPcaBasis = tag("PCAB"), kPcaCoefficients = tag("PCAC"),
                        kDecoderHalf = tag("DECH"), kLatentsHalf = tag("LATH"), kIdsZstd = tag("TXIZ"),
                        kModulation = tag("TXSC"), kModulationRgb = tag("TXCH"), kDecoderInt8 = tag("DEC8"), kDirsZstd = tag("DIRZ"), kMetaZstd = tag("METZ"), kHoldoutZstd = tag("HOLZ"),
                        kPlanes = tag("DPLN");

std::string tagText(std::uint32_t t) {
  const unsigned char bytes[4] = {static_cast<unsigned char>(t), static_cast<unsigned char>(t >> 8),
                                  static_cast<unsigned char>(t >> 16), static_cast<unsigned char>(t >> 24)};
  return printableBytes(bytes, 4);
}

std::string sectionLabel(std::uint32_t t) {
  const char* what = t == kInfo      ? "material info"
                     : t == kDirs    ? "directions"
                     : t == kDirsZstd ? "directions, zstd-coded"
                     : t == kDecoder ? "decoder"
                     : t == kLatents ? "latents"
                     : t == kIds     ? "id list"
                     : t == kHoldout ? "hold-out images"
                     : t == kEncoder ? "encoder"
                     : t == kMeta    ? "metadata"
                     : t == kPcaMean ? "PCA mean"
                     : t == kPcaBasis ? "PCA basis"
                     : t == kPcaCoefficients ? "PCA coefficients"
                     : t == kDecoderHalf ? "decoder, half precision"
                     : t == kDecoderInt8 ? "decoder, 8-bit weights"
                     : t == kLatentsHalf ? "latents, half precision"
                     : t == kIdsZstd ? "id list, zstd-coded"
                     : t == kModulation ? "per-texel modulation"
                     : t == kModulationRgb ? "per-texel modulation, per channel"
                     : t == kMetaZstd ? "metadata, zstd-coded"
                     : t == kHoldoutZstd ? "hold-out images, zstd-coded"
                     : t == kPlanes ? "direction planes"
                                     : nullptr;
  return "section '" + tagText(t) + "'" + (what ? std::string(" (") + what + ")" : std::string());
}

std::string hex32(std::uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%08" PRIx32, v);
  return buf;
}

// Stored enum codes: independent of the in-memory enums so those can change freely.
std::uint8_t layoutCode(Layout l) {
  return l == Layout::Ubo2003 ? 1 : l == Layout::Utia ? 2 : l == Layout::Ubo2014 ? 3 : 0;
}
Layout layoutFromCode(std::uint8_t c) {
  return c == 1 ? Layout::Ubo2003 : c == 2 ? Layout::Utia : c == 3 ? Layout::Ubo2014 : Layout::Unknown;
}
std::uint8_t sampleTypeCode(SampleType t) { return t == SampleType::Srgb8 ? 1 : 2; }

// ---- Validation helpers

bool allFinite(const std::vector<float>& v) {
  return std::all_of(v.begin(), v.end(), [](float x) { return std::isfinite(x); });
}

// Nesting depth of a JSON text (brackets outside strings); bounds the parser's work on
// hostile metadata before nlohmann sees it.
int jsonDepth(const std::string& text) {
  int depth = 0, maxDepth = 0;
  bool inString = false, escape = false;
  for (char c : text) {
    if (inString) {
      if (escape) escape = false;
      else if (c == '\\') escape = true;
      else if (c == '"') inString = false;
    } else if (c == '"') {
      inString = true;
    } else if (c == '{' || c == '[') {
      maxDepth = std::max(maxDepth, ++depth);
    } else if (c == '}' || c == ']') {
      --depth;
    }
  }
  return maxDepth;
}

void checkMetadata(const std::string& json, const std::string& name) {
  if (jsonDepth(json) > kMaxJsonDepth)
    throw fileError(name, "metadata JSON is nested deeper than " + std::to_string(kMaxJsonDepth) + " levels");
  auto first = json.find_first_not_of(" \t\r\n");
  if (first == std::string::npos || json[first] != '{' || !nlohmann::json::accept(json))
    throw fileError(name, "metadata is not a valid JSON object");
}

// ---- Coded parts (format 1.2), shared by the writer and computeSizes

// Records of `width` bytes as byte planes (byte 0 of every record, then byte 1...), and back:
// neighbouring texels share clusters and codes, and the planes put the repetitive bytes
// together for zstd.
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

// Integers of `width` bytes (little-endian) as byte planes, and back.
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

// The codes column by column (all texels' column 0, then column 1...), as byte planes.
std::vector<std::uint8_t> codedModulation(const TexelModulation& m, bool zstd) {
  const int columns = std::max(m.columns(), 1);
  const std::size_t texels = m.codes.size() / columns;
  std::vector<std::uint32_t> byTerm(m.codes.size());
  for (int r = 0; r < columns; ++r)
    for (std::size_t t = 0; t < texels; ++t) byTerm[r * texels + t] = m.codes[t * columns + r];
  auto planes = toBytePlanes(byTerm, modulationCodeBytes(m.bits));
  return zstd ? zstdCompress(planes.data(), planes.size()) : planes;
}

// ---- 8-bit decoder weights (DEC8)

// The smallest normal half value 2^-14: a row's scale is never below it, so a row of tiny
// weights keeps codes below 127 and still re-quantizes to itself.
constexpr float kMinInt8Scale = 6.103515625e-05f;

// Scale of one output row: the smallest half value s >= 2^-14 with max|w| / s <= 127. Then
// the row's largest weight is code +-127 (unless the scale is the minimum), and quantizing
// q x s again gives the same scale and codes: the writer re-derives them from the values.
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

// Direction planes follow the decoder's storage: float32 with a float32 decoder, half otherwise.
bool storagePlanesHalf(const CompressedBtf& b) { return b.storage.decoderHalf || b.storage.decoderInt8; }

}  // namespace

std::string storageDescription(const CompressedBtf& btf) {
  if (btf.isPca())
    return std::string("float32 parts, directions ") + (btf.storage.directionsZstd ? "zstd" : "f64") + ", metadata " +
           (btf.storage.metadataZstd ? "zstd" : "raw");
  return std::string("decoder ") + (btf.storage.decoderInt8 ? "int8" : btf.storage.decoderHalf ? "half" : "float32") +
         ", latents " + (btf.storage.latentsHalf ? "half" : "float32") +
         (btf.method == CodecMethod::ClusteredNeural ? std::string(", ids ") + (btf.storage.idsZstd ? "zstd" : "raw")
                                                     : std::string()) +
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
  if (storagePlanesHalf(btf))
    for (float& v : btf.planes.values) v = roundToHalf(v);
}

// ---- Names, sizes

std::string codecMethodName(CodecMethod m) {
  switch (m) {
    case CodecMethod::ClusteredNeural: return "clustered-neural";
    case CodecMethod::PerTexelNeural: return "per-texel-neural";
    case CodecMethod::Pca: return "pca";
  }
  return "unknown";
}

int idWidthForClusters(std::int64_t k) {
  if (k <= 0x100) return 1;
  if (k <= 0x10000) return 2;
  return 4;
}

NbtfSizes computeSizes(const CompressedBtf& btf, std::uint64_t fileBytes) {
  NbtfSizes s;
  for (const auto& layer : btf.decoder.layers) s.decoderParameters += layer.parameterCount();
  s.decoderBytesPerValue = btf.storage.decoderInt8 ? 1 : btf.storage.decoderHalf ? 2 : 4;
  s.latentBytesPerValue = btf.storage.latentsHalf ? 2 : 4;
  s.decoder = s.decoderParameters * s.decoderBytesPerValue;
  if (btf.storage.decoderInt8)  // 1-byte weights, a 2-byte scale and a 2-byte bias per output
    for (const auto& layer : btf.decoder.layers) s.decoder += 3 * layer.bias.size();
  s.latentRows = static_cast<std::uint64_t>(std::max(btf.latentRows, 0));
  s.latentDim = btf.latentDim;
  const std::uint64_t latentValues = s.latentRows * static_cast<std::uint64_t>(std::max(btf.latentDim, 0));
  s.latents = latentValues * s.latentBytesPerValue;
  s.texels = static_cast<std::uint64_t>(std::max(btf.numTexels(), 0));
  s.images = static_cast<std::uint64_t>(btf.numImages());
  if (btf.isPca()) {
    s.pca = true;
    s.pcaComponents = btf.latentDim;
    const std::uint64_t c = static_cast<std::uint64_t>(std::max(btf.latentDim, 0));
    s.pcaMean = s.images * 3 * 4;
    s.pcaBasis = s.images * 3 * c * 4;
    s.pcaCoefficients = s.texels * c * 4;
    s.latents = 0;
  }
  if (btf.method == CodecMethod::ClusteredNeural) {
    s.idWidth = idWidthForClusters(btf.latentRows);
    s.ids = s.texels * static_cast<std::uint64_t>(s.idWidth);
    s.idsPaper = s.texels * 4;
    if (btf.storage.idsZstd && btf.ids.size() == s.texels) {
      s.idsZstd = true;
      s.ids = codedIds(btf).size();
    }
  }
  if (!btf.modulation.empty()) {
    s.modulationTerms = btf.modulation.terms;
    s.modulationChannels = btf.modulation.channels;
    s.modulationBits = btf.modulation.bits;
    s.modulation = codedModulation(btf.modulation, btf.storage.modulationZstd).size();
  }
  if (!btf.planes.empty()) {
    s.planeResolution = btf.planes.resolution;
    s.planeFeatures = btf.planes.features;
    s.planeBytesPerValue = storagePlanesHalf(btf) ? 2 : 4;
    s.planes = btf.planes.valueCount() * s.planeBytesPerValue;
  }
  s.total = s.decoder + s.planes + s.latents + s.ids + s.modulation + s.pcaMean + s.pcaBasis + s.pcaCoefficients;
  // The same model stored the paper's way: float32 decoder, planes and latents, 4-byte ids.
  s.totalPaper = btf.isPca() ? s.total
                             : s.decoderParameters * 4 + btf.planes.valueCount() * 4 + latentValues * 4 + s.idsPaper +
                                   s.modulation;
  s.rawFloat32 = s.texels * s.images * 3 * 4;
  s.fileBytes = fileBytes;
  s.ratio = s.total ? static_cast<double>(s.rawFloat32) / static_cast<double>(s.total) : 0;
  s.ratioPaper = s.totalPaper ? static_cast<double>(s.rawFloat32) / static_cast<double>(s.totalPaper) : 0;
  return s;
}

namespace {
std::string withCommas(std::uint64_t v) {
  std::string digits = std::to_string(v), out;
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}
std::string kib(std::uint64_t bytes) {
  char buf[32];
  if (bytes >= 10u << 20) std::snprintf(buf, sizeof buf, "%.1f MiB", bytes / (1024.0 * 1024.0));
  else std::snprintf(buf, sizeof buf, "%.1f KiB", bytes / 1024.0);
  return buf;
}
std::string row(const char* part, std::uint64_t bytes, const std::string& note) {
  char buf[256];
  std::snprintf(buf, sizeof buf, "  %-12s %14s B %14s  %s\n", part, withCommas(bytes).c_str(), kib(bytes).c_str(),
                note.c_str());
  return buf;
}
}  // namespace

std::string formatSizeTable(const NbtfSizes& s) {
  auto rawAndRatio = [&] {
    char ratio[160];
    std::snprintf(ratio, sizeof ratio, "  %-12s 1 : %.1f (raw float32 / total)\n", "ratio", s.ratio);
    return row("raw float32", s.rawFloat32,
               withCommas(s.texels) + " texels x " + withCommas(s.images) + " images x 3 x 4 bytes") +
           ratio;
  };
  if (s.pca) {
    // The baseline's parts, in the same table shape and units as the neural methods.
    std::string out = "sizes (PCA baseline, parts as stored in float32; KiB = 1024 bytes, the paper's KB)\n";
    std::string c = std::to_string(s.pcaComponents);
    out += row("mean", s.pcaMean, withCommas(s.images) + " images x 3 x 4 bytes");
    out += row("basis", s.pcaBasis, withCommas(s.images) + " images x 3 x " + c + " components x 4 bytes");
    out += row("coefficients", s.pcaCoefficients, withCommas(s.texels) + " texels x " + c + " components x 4 bytes");
    out += row("total", s.total, "mean + basis + coefficients");
    out += rawAndRatio();
    if (s.fileBytes) out += row("file", s.fileBytes, "actual .nbtf size (adds directions, header, metadata, checksums)");
    return out;
  }
  std::string out = "sizes (as in the paper's Table 1, as stored; KiB = 1024 bytes, the paper's KB)\n";
  auto precision = [](int bytes) { return bytes == 2 ? std::string(" x 2 bytes (half)") : std::string(" x 4 bytes (float32)"); };
  out += row("decoder", s.decoder,
             withCommas(s.decoderParameters) + " parameters" +
                 (s.decoderBytesPerValue == 1 ? std::string(": 8-bit weights, half scale per row, half biases")
                                              : precision(s.decoderBytesPerValue)));
  if (s.planes)
    out += row("planes", s.planes,
               "3 direction planes x " + std::to_string(s.planeResolution) + " x " + std::to_string(s.planeResolution) +
                   " points x " + std::to_string(s.planeFeatures) + " features" + precision(s.planeBytesPerValue));
  out += row("latents", s.latents,
             withCommas(s.latentRows) + " x " + std::to_string(s.latentDim) + precision(s.latentBytesPerValue));
  if (s.idWidth && s.idsZstd) {
    char note[160];
    std::snprintf(note, sizeof note, "%s texels x %d byte%s, zstd-coded (%.2f bits per texel)",
                  withCommas(s.texels).c_str(), s.idWidth, s.idWidth > 1 ? "s" : "",
                  s.texels ? 8.0 * s.ids / s.texels : 0.0);
    out += row("id list", s.ids, note);
  } else if (s.idWidth) {
    out += row("id list", s.ids,
               withCommas(s.texels) + " texels x " + std::to_string(s.idWidth) + " byte" +
                   (s.idWidth > 1 ? "s" : "") + " (smallest width that fits k; the paper used 4)");
  } else {
    out += row("id list", 0, "none (per-texel: one latent per texel)");
  }
  if (s.modulationTerms) {
    char note[200];
    const int columns = s.modulationTerms * s.modulationChannels;
    std::snprintf(note, sizeof note, "%s texels x %d coefficient%s%s x %d-bit codes, %.2f bits per texel as stored",
                  withCommas(s.texels).c_str(), columns, columns > 1 ? "s" : "",
                  s.modulationChannels > 1 ? " (per RGB channel)" : "", s.modulationBits,
                  s.texels ? 8.0 * s.modulation / s.texels : 0.0);
    out += row("per-texel", s.modulation, note);
  }
  out += row("total", s.total,
             std::string(s.planes ? "decoder + planes" : "decoder") + " + latents + id list" +
                 (s.modulationTerms ? " + per-texel" : ""));
  out += rawAndRatio();
  char ratio[160];
  if (s.idWidth && s.totalPaper != s.total) {
    std::snprintf(ratio, sizeof ratio, "  %-12s total %s, 1 : %.1f (stored the paper's way: float32, 4-byte ids)\n",
                  "paper-style", kib(s.totalPaper).c_str(), s.ratioPaper);
    out += ratio;
  }
  if (s.fileBytes)
    out += row("file", s.fileBytes, "actual .nbtf size (adds directions, header, metadata, checksums)");
  return out;
}

// ---- Validation

void CompressedBtf::validate(const std::string& name) const {
  auto fail = [&](const std::string& m) { return fileError(name, m); };
  if (method != CodecMethod::ClusteredNeural && method != CodecMethod::PerTexelNeural && method != CodecMethod::Pca)
    throw fail("unknown method code " + std::to_string(static_cast<int>(method)));
  if (!isDirectionEncoding(static_cast<int>(directionEncoding)))
    throw fail("unknown direction encoding code " + std::to_string(static_cast<int>(directionEncoding)));
  if (valueSpace != ValueSpace::LinearOverAlpha)
    throw fail("unknown value space code " + std::to_string(static_cast<int>(valueSpace)));

  // Geometry
  if (width < 1 || height < 1 || width > int(kMaxSide) || height > int(kMaxSide))
    throw fail("texel size " + std::to_string(width) + " x " + std::to_string(height) + " is out of range");
  if (static_cast<std::int64_t>(width) * height > INT_MAX) throw fail("too many texels");
  if (sourceWidth < 1 || sourceHeight < 1 || sourceWidth > int(kMaxSide) || sourceHeight > int(kMaxSide))
    throw fail("source image size " + std::to_string(sourceWidth) + " x " + std::to_string(sourceHeight) +
               " is out of range");
  if (crop.empty()) {
    if (width != sourceWidth || height != sourceHeight)
      throw fail("texel size differs from the source image size but no crop is recorded");
  } else {
    if (crop.x < 0 || crop.y < 0 || crop.width < 1 || crop.height < 1 ||
        static_cast<std::int64_t>(crop.x) + crop.width > sourceWidth ||
        static_cast<std::int64_t>(crop.y) + crop.height > sourceHeight)
      throw fail("crop " + std::to_string(crop.x) + "," + std::to_string(crop.y) + "," + std::to_string(crop.width) +
                 "," + std::to_string(crop.height) + " lies outside the " + std::to_string(sourceWidth) + " x " +
                 std::to_string(sourceHeight) + " source images");
    if (crop.width != width || crop.height != height) throw fail("crop size differs from the texel size");
  }
  if (lights.empty() || views.empty()) throw fail("no light or view directions");
  if (static_cast<std::int64_t>(lights.size()) * static_cast<std::int64_t>(views.size()) > INT_MAX)
    throw fail("too many images");
  for (std::size_t i = 0; i < lights.size(); ++i) {
    try {
      checkHemisphere(lights[i], "light " + std::to_string(i));
    } catch (const Error& e) {
      throw fail(e.what());
    }
  }
  for (std::size_t i = 0; i < views.size(); ++i) {
    try {
      checkHemisphere(views[i], "view " + std::to_string(i));
    } catch (const Error& e) {
      throw fail(e.what());
    }
  }
  if (!std::isfinite(alpha) || !(alpha > 0)) throw fail("alpha must be a finite positive number");

  if (isPca()) validatePca(name);
  else validateNeural(name);

  // Provenance
  for (std::size_t i = 0; i < holdoutImages.size(); ++i) {
    int h = holdoutImages[i];
    if (h < 0 || h >= numImages())
      throw fail("hold-out image index " + std::to_string(h) + " is outside [0, " + std::to_string(numImages()) + ")");
    if (i && h <= holdoutImages[i - 1]) throw fail("hold-out image indices are not strictly ascending");
  }
  checkMetadata(metadataJson, name);
}

void CompressedBtf::validatePca(const std::string& name) const {
  auto fail = [&](const std::string& m) { return fileError(name, m); };
  const std::int64_t rows = 3 * static_cast<std::int64_t>(numImages());
  const int texels = numTexels();
  if (!decoder.layers.empty() || !ids.empty()) throw fail("PCA file has a decoder or an id list");
  const std::int64_t maxComponents = std::min<std::int64_t>({rows, texels, kMaxPcaComponents});
  if (latentDim < 1 || latentDim > maxComponents)
    throw fail(std::to_string(latentDim) + " PCA components, expected 1 to " + std::to_string(maxComponents) +
               " (at most min(texels, 3 x images))");
  if (latentRows != texels)
    throw fail("PCA file has " + std::to_string(latentRows) + " coefficient rows for " + std::to_string(texels) +
               " texels");
  const std::size_t c = static_cast<std::size_t>(latentDim);
  if (pcaMean.size() != static_cast<std::size_t>(rows))
    throw fail("PCA mean holds " + std::to_string(pcaMean.size()) + " values, expected 3 x " +
               std::to_string(numImages()) + " images");
  if (pcaBasis.size() != static_cast<std::size_t>(rows) * c)
    throw fail("PCA basis holds " + std::to_string(pcaBasis.size()) + " values, expected " + std::to_string(rows) +
               " x " + std::to_string(c));
  if (latents.size() != static_cast<std::size_t>(texels) * c)
    throw fail("PCA coefficients hold " + std::to_string(latents.size()) + " values, expected " +
               std::to_string(texels) + " x " + std::to_string(c));
  if (!allFinite(pcaMean)) throw fail("PCA mean contains non-finite values (NaN or Inf)");
  if (!allFinite(pcaBasis)) throw fail("PCA basis contains non-finite values (NaN or Inf)");
  if (!allFinite(latents)) throw fail("PCA coefficients contain non-finite values (NaN or Inf)");
}

void CompressedBtf::validateNeural(const std::string& name) const {
  auto fail = [&](const std::string& m) { return fileError(name, m); };
  // Decoder: latent + direction inputs (util/directions.h) in, RGB out, shapes chained.
  if (latentDim < 1 || latentDim > int(kMaxLatentDim)) throw fail("latent dimension " + std::to_string(latentDim) + " is out of range");
  if (decoder.layers.empty()) throw fail("decoder has no layers");
  for (std::size_t i = 0; i < decoder.layers.size(); ++i) {
    const DenseLayer& l = decoder.layers[i];
    std::string which = "decoder layer " + std::to_string(i);
    if (l.in < 1 || l.out < 1 || l.in > int(kMaxLayerWidth) || l.out > int(kMaxLayerWidth))
      throw fail(which + " has shape " + std::to_string(l.out) + " x " + std::to_string(l.in));
    const int directionInputs = this->directionInputs();
    int expectedIn = i == 0 ? latentDim + directionInputs : decoder.layers[i - 1].out;
    if (l.in != expectedIn)
      throw fail(which + " takes " + std::to_string(l.in) + " inputs, expected " + std::to_string(expectedIn) +
                 (i == 0 ? " (latent + " + std::to_string(directionInputs) + " direction inputs, " +
                              directionEncodingName(directionEncoding) +
                              (planes.empty() ? std::string() : " + direction planes") + ")"
                        : std::string(" (previous layer's outputs)")));
    if (l.weight.size() != static_cast<std::size_t>(l.in) * l.out || l.bias.size() != static_cast<std::size_t>(l.out))
      throw fail(which + " has " + std::to_string(l.weight.size()) + " weights and " + std::to_string(l.bias.size()) +
                 " biases for shape " + std::to_string(l.out) + " x " + std::to_string(l.in));
    if (l.activation != Activation::None && l.activation != Activation::Relu && l.activation != Activation::Sigmoid)
      throw fail(which + " has unknown activation code " + std::to_string(static_cast<int>(l.activation)));
    if (!allFinite(l.weight) || !allFinite(l.bias)) throw fail(which + " has non-finite parameters (NaN or Inf)");
  }
  const int terms = modulation.empty() ? 1 : modulation.terms;
  if (decoder.layers.back().out != 3 * terms)
    throw fail("decoder outputs " + std::to_string(decoder.layers.back().out) + " values, expected " +
               (terms == 1 ? std::string("3 (RGB)") : std::to_string(3 * terms) + " (RGB x " + std::to_string(terms) +
                                                          " per-texel modulation terms)"));

  // Direction planes
  if (!planes.empty()) {
    if (planes.features < 0 || planes.features > DirectionPlanes::kMaxFeatures || planes.resolution < 2 ||
        planes.resolution > DirectionPlanes::kMaxResolution)
      throw fail("direction planes of " + std::to_string(planes.resolution) + " x " + std::to_string(planes.resolution) +
                 " points x " + std::to_string(planes.features) + " features are out of range (2.." +
                 std::to_string(DirectionPlanes::kMaxResolution) + " points, 1.." +
                 std::to_string(DirectionPlanes::kMaxFeatures) + " features)");
    if (planes.values.size() != planes.valueCount())
      throw fail("direction planes hold " + std::to_string(planes.values.size()) + " values, expected " +
                 std::to_string(planes.valueCount()));
    if (!allFinite(planes.values)) throw fail("direction planes contain non-finite values (NaN or Inf)");
  } else if (!planes.values.empty()) {
    throw fail("direction plane values without features");
  }

  // Latents and ids
  if (latentRows < 1) throw fail("no latents");
  if (latents.size() != static_cast<std::size_t>(latentRows) * latentDim)
    throw fail("latents hold " + std::to_string(latents.size()) + " values, expected " + std::to_string(latentRows) +
               " x " + std::to_string(latentDim));
  if (!allFinite(latents)) throw fail("latents contain non-finite values (NaN or Inf)");
  int texels = numTexels();
  if (method == CodecMethod::ClusteredNeural) {
    if (ids.size() != static_cast<std::size_t>(texels))
      throw fail("id list has " + std::to_string(ids.size()) + " entries, expected one per texel (" +
                 std::to_string(texels) + ")");
    for (std::size_t t = 0; t < ids.size(); ++t)
      if (ids[t] < 0 || ids[t] >= latentRows)
        throw fail("id of texel " + std::to_string(t) + " is " + std::to_string(ids[t]) + ", outside [0, " +
                   std::to_string(latentRows) + ")");
  } else {
    if (!ids.empty()) throw fail("per-texel file has an id list");
    if (latentRows != texels)
      throw fail("per-texel file has " + std::to_string(latentRows) + " latents for " + std::to_string(texels) +
                 " texels");
  }
  if (!pcaMean.empty() || !pcaBasis.empty()) throw fail(codecMethodName(method) + " file has a PCA mean or basis");

  // Half-precision storage holds exactly the values in memory (roundToStorage).
  auto halfExact = [](const std::vector<float>& v) {
    return std::all_of(v.begin(), v.end(), [](float x) { return roundToHalf(x) == x; });
  };
  if (storage.decoderInt8 && storage.decoderHalf) throw fail("decoder storage is both half and 8-bit");
  if (storage.decoderInt8)
    for (const DenseLayer& l : decoder.layers) {
      bool exact = halfExact(l.bias);
      for (int o = 0; o < l.out && exact; ++o) {
        const float* row = l.weight.data() + static_cast<std::size_t>(o) * l.in;
        const float scale = int8RowScale(row, l.in);
        for (int i = 0; i < l.in && exact; ++i) exact = static_cast<float>(int8Code(row[i], scale)) * scale == row[i];
      }
      if (!exact)
        throw fail("decoder is to be stored with 8-bit weights and half biases but holds values they cannot "
                   "represent (round them with roundToStorage first)");
    }
  if (storage.decoderHalf)
    for (const DenseLayer& l : decoder.layers)
      if (!halfExact(l.weight) || !halfExact(l.bias))
        throw fail("decoder is to be stored in half precision but holds values that half cannot represent "
                   "(round them with roundToStorage first)");
  if (storagePlanesHalf(*this) && !halfExact(planes.values))
    throw fail("direction planes are to be stored in half precision but hold values that half cannot represent");
  if (storage.latentsHalf && !halfExact(latents))
    throw fail("latents are to be stored in half precision but hold values that half cannot represent");

  // Per-texel modulation
  if (modulation.empty()) {
    if (!modulation.codes.empty()) throw fail("modulation codes without modulation terms");
    return;
  }
  if (method != CodecMethod::ClusteredNeural) throw fail("per-texel modulation is only defined for the clustered method");
  if (modulation.terms < 1 || modulation.terms > kMaxModulationTerms)
    throw fail("modulation has " + std::to_string(modulation.terms) + " terms, expected 1 to " +
               std::to_string(kMaxModulationTerms));
  if (modulation.bits < 1 || modulation.bits > 16)
    throw fail("modulation codes have " + std::to_string(modulation.bits) + " bits, expected 1 to 16");
  if (modulation.channels != 1 && modulation.channels != 3)
    throw fail("modulation has " + std::to_string(modulation.channels) + " channels, expected 1 or 3");
  const int columns = modulation.columns();
  if (modulation.codes.size() != static_cast<std::size_t>(texels) * columns)
    throw fail("modulation holds " + std::to_string(modulation.codes.size()) + " codes, expected " +
               std::to_string(texels) + " texels x " + std::to_string(columns));
  for (int r = 0; r < columns; ++r) {
    const float lo = modulation.minimum[r], hi = modulation.maximum[r];
    if (!std::isfinite(lo) || !std::isfinite(hi) || lo > hi || lo < -kMaxModulationMagnitude ||
        hi > kMaxModulationMagnitude)
      throw fail("modulation range of term " + std::to_string(r / modulation.channels) +
                 (modulation.channels > 1 ? ", channel " + std::to_string(r % modulation.channels) : std::string()) +
                 " is invalid (" + std::to_string(lo) + " .. " + std::to_string(hi) + ")");
  }
  const std::uint32_t maxCode = (1u << modulation.bits) - 1;
  for (std::size_t i = 0; i < modulation.codes.size(); ++i)
    if (modulation.codes[i] > maxCode)
      throw fail("modulation code " + std::to_string(modulation.codes[i]) + " of texel " +
                 std::to_string(i / columns) + " exceeds " + std::to_string(modulation.bits) + " bits");
}

// ---- Writing

namespace {

void addSection(ByteWriter& file, std::uint32_t t, bool required, ByteWriter& payload) {
  const auto& p = payload.bytes();
  file.u32(t);
  file.u32(required ? kSectionRequired : 0);
  file.u64(p.size());
  file.u32(crc32(p.data(), p.size()));
  file.u32(0);
  file.raw(p.data(), p.size());
  file.zeros((kAlign - p.size() % kAlign) % kAlign);
}

void writeFloats(ByteWriter& w, const std::vector<float>& v) {
  for (float x : v) w.f32(x);
}
void writeValues(ByteWriter& w, const std::vector<float>& v, bool half) {
  if (!half) return writeFloats(w, v);
  for (float x : v) w.u16(floatToHalf(x));
}

// Files stored as in 1.0 (or 1.1 for PCA) are written as such, so older readers open them.
bool usesFormat12(const CompressedBtf& b) {
  if (b.isPca()) return false;
  return b.storage.decoderHalf || b.storage.latentsHalf || !b.modulation.empty() ||
         (b.storage.idsZstd && b.method == CodecMethod::ClusteredNeural);
}

}  // namespace

std::vector<std::uint8_t> serializeNbtf(const CompressedBtf& btf) {
  btf.validate();
  ByteWriter file;
  file.raw(kNbtfMagic, sizeof kNbtfMagic);
  file.u16(kNbtfFormatMajor);
  // The lowest version that describes the file.
  file.u16(!btf.planes.empty()                                                 ? std::uint16_t(8)
           : btf.directionEncoding == DirectionEncoding::StereographicFourier2  ? std::uint16_t(7)
           : btf.directionEncoding == DirectionEncoding::StereographicFourier ? std::uint16_t(6)
           : btf.modulation.channels != 1 ? std::uint16_t(5)
           : btf.storage.metadataZstd || btf.storage.decoderInt8 || btf.storage.directionsZstd ? std::uint16_t(4)
           : btf.directionEncoding != DirectionEncoding::Stereographic ? std::uint16_t(3)
           : usesFormat12(btf)                                       ? std::uint16_t(2)
           : btf.isPca()                                             ? std::uint16_t(1)
                                                                     : std::uint16_t(0));
  file.u32(0);  // header flags (none defined)
  file.u64(0);  // file size, patched below
  file.u32(0);  // body CRC, patched below
  file.u32(0);  // header CRC, patched below

  {
    ByteWriter w;
    w.u8(static_cast<std::uint8_t>(btf.method));
    w.u8(static_cast<std::uint8_t>(btf.directionEncoding));
    w.u8(static_cast<std::uint8_t>(btf.valueSpace));
    w.u8(layoutCode(btf.layout));
    w.u8(sampleTypeCode(btf.sourceSampleType));
    w.zeros(3);
    w.u32(static_cast<std::uint32_t>(btf.width));
    w.u32(static_cast<std::uint32_t>(btf.height));
    w.u32(static_cast<std::uint32_t>(btf.sourceWidth));
    w.u32(static_cast<std::uint32_t>(btf.sourceHeight));
    w.u32(static_cast<std::uint32_t>(btf.crop.x));
    w.u32(static_cast<std::uint32_t>(btf.crop.y));
    w.u32(static_cast<std::uint32_t>(btf.crop.width));
    w.u32(static_cast<std::uint32_t>(btf.crop.height));
    w.f32(btf.alpha);
    w.u32(static_cast<std::uint32_t>(btf.latentDim));
    w.u32(static_cast<std::uint32_t>(btf.latentRows));
    w.u32(0);  // reserved
    addSection(file, kInfo, true, w);
  }
  {
    // u32 lights, u32 views, then (f64 theta, f64 phi) per direction, lights first; DIRZ:
    // those pairs as 8 byte planes in one zstd frame (regular grids leave most planes zero).
    ByteWriter pairs;
    for (const auto* set : {&btf.lights, &btf.views})
      for (const Direction& d : *set) {
        pairs.f64(d.thetaDeg);
        pairs.f64(d.phiDeg);
      }
    ByteWriter w;
    w.u32(static_cast<std::uint32_t>(btf.lights.size()));
    w.u32(static_cast<std::uint32_t>(btf.views.size()));
    if (btf.storage.directionsZstd) {
      auto planes = bytePlanesOf(pairs.bytes(), 8);
      auto coded = zstdCompress(planes.data(), planes.size());
      w.raw(coded.data(), coded.size());
    } else {
      w.raw(pairs.bytes().data(), pairs.size());
    }
    addSection(file, btf.storage.directionsZstd ? kDirsZstd : kDirs, true, w);
  }
  if (btf.isPca()) {
    // Mean, basis and coefficients (docs/file_format.md): all required, so a 1.0 reader
    // refuses the file by name instead of missing its decoder.
    ByteWriter mean;
    mean.u32(static_cast<std::uint32_t>(btf.pcaMean.size()));
    writeFloats(mean, btf.pcaMean);
    addSection(file, kPcaMean, true, mean);
    ByteWriter basis;
    basis.u32(static_cast<std::uint32_t>(btf.pcaMean.size()));
    basis.u32(static_cast<std::uint32_t>(btf.latentDim));
    writeFloats(basis, btf.pcaBasis);
    addSection(file, kPcaBasis, true, basis);
    ByteWriter coefficients;
    coefficients.u32(static_cast<std::uint32_t>(btf.latentRows));
    coefficients.u32(static_cast<std::uint32_t>(btf.latentDim));
    writeFloats(coefficients, btf.latents);
    addSection(file, kPcaCoefficients, true, coefficients);
  }
  if (!btf.isPca()) {
    // Per layer: u32 in, u32 out, u8 activation, 3 reserved, then float32 or half weights and
    // biases; DEC8: out half scales, out x in signed 8-bit codes (weight = code x its row's
    // scale), out half biases.
    const bool int8 = btf.storage.decoderInt8;
    ByteWriter w;
    w.u32(static_cast<std::uint32_t>(btf.decoder.layers.size()));
    for (const DenseLayer& l : btf.decoder.layers) {
      w.u32(static_cast<std::uint32_t>(l.in));
      w.u32(static_cast<std::uint32_t>(l.out));
      w.u8(static_cast<std::uint8_t>(l.activation));
      w.zeros(3);
      if (int8) {
        std::vector<float> scales(l.out);
        for (int o = 0; o < l.out; ++o) scales[o] = int8RowScale(l.weight.data() + static_cast<std::size_t>(o) * l.in, l.in);
        writeValues(w, scales, true);
        for (std::size_t i = 0; i < l.weight.size(); ++i)
          w.u8(static_cast<std::uint8_t>(static_cast<std::int8_t>(int8Code(l.weight[i], scales[i / l.in]))));
        writeValues(w, l.bias, true);
      } else {
        writeValues(w, l.weight, btf.storage.decoderHalf);
        writeValues(w, l.bias, btf.storage.decoderHalf);
      }
    }
    addSection(file, int8 ? kDecoderInt8 : btf.storage.decoderHalf ? kDecoderHalf : kDecoder, true, w);
  }
  if (!btf.planes.empty()) {
    // u32 resolution R, u32 features F, u8 1 = half values (0 = float32), 3 reserved, then
    // 3 x R x R x F values: plane (light, view, half vector), row y, column x, feature.
    ByteWriter w;
    const bool half = storagePlanesHalf(btf);
    w.u32(static_cast<std::uint32_t>(btf.planes.resolution));
    w.u32(static_cast<std::uint32_t>(btf.planes.features));
    w.u8(half ? 1 : 0);
    w.zeros(3);
    writeValues(w, btf.planes.values, half);
    addSection(file, kPlanes, true, w);
  }
  if (!btf.isPca()) {
    ByteWriter w;
    w.u32(static_cast<std::uint32_t>(btf.latentRows));
    w.u32(static_cast<std::uint32_t>(btf.latentDim));
    writeValues(w, btf.latents, btf.storage.latentsHalf);
    addSection(file, btf.storage.latentsHalf ? kLatentsHalf : kLatents, true, w);
  }
  if (btf.method == CodecMethod::ClusteredNeural && btf.storage.idsZstd) {
    // u32 count, u8 width, u8 coding (1 = zstd over byte planes), 2 reserved, the frame.
    ByteWriter w;
    w.u32(static_cast<std::uint32_t>(btf.ids.size()));
    w.u8(static_cast<std::uint8_t>(idWidthForClusters(btf.latentRows)));
    w.u8(1);
    w.zeros(2);
    auto coded = codedIds(btf);
    w.raw(coded.data(), coded.size());
    addSection(file, kIdsZstd, true, w);
  } else if (btf.method == CodecMethod::ClusteredNeural) {
    ByteWriter w;
    int width = idWidthForClusters(btf.latentRows);
    w.u32(static_cast<std::uint32_t>(btf.ids.size()));
    w.u8(static_cast<std::uint8_t>(width));
    w.zeros(3);
    for (std::int32_t id : btf.ids) {
      auto v = static_cast<std::uint32_t>(id);
      if (width == 1) w.u8(static_cast<std::uint8_t>(v));
      else if (width == 2) w.u16(static_cast<std::uint16_t>(v));
      else w.u32(v);
    }
    addSection(file, kIds, true, w);
  }
  if (!btf.modulation.empty()) {
    // u32 texels, u8 terms, u8 bits, u8 coding (0 raw, 1 zstd), u8 channels (TXCH: 3; TXSC:
    // reserved, 0), columns x (f32 min, f32 max), then the codes (byte planes of the column
    // planes). Per-channel coefficients get their own tag, so that a reader before 1.5
    // refuses them instead of misreading them.
    const TexelModulation& m = btf.modulation;
    const bool perChannel = m.channels != 1;
    ByteWriter w;
    w.u32(static_cast<std::uint32_t>(m.codes.size() / m.columns()));
    w.u8(static_cast<std::uint8_t>(m.terms));
    w.u8(static_cast<std::uint8_t>(m.bits));
    w.u8(btf.storage.modulationZstd ? 1 : 0);
    w.u8(perChannel ? static_cast<std::uint8_t>(m.channels) : 0);
    for (int r = 0; r < m.columns(); ++r) {
      w.f32(m.minimum[r]);
      w.f32(m.maximum[r]);
    }
    auto coded = codedModulation(m, btf.storage.modulationZstd);
    w.raw(coded.data(), coded.size());
    addSection(file, perChannel ? kModulationRgb : kModulation, true, w);
  }
  if (!btf.holdoutImages.empty() && btf.storage.metadataZstd) {
    // u32 count, u32 images, a zstd frame of the images' bit mask (bit i of byte i / 8).
    ByteWriter w;
    w.u32(static_cast<std::uint32_t>(btf.holdoutImages.size()));
    w.u32(static_cast<std::uint32_t>(btf.numImages()));
    std::vector<std::uint8_t> mask((static_cast<std::size_t>(btf.numImages()) + 7) / 8, 0);
    for (int h : btf.holdoutImages) mask[h / 8] |= static_cast<std::uint8_t>(1u << (h % 8));
    auto coded = zstdCompress(mask.data(), mask.size());
    w.raw(coded.data(), coded.size());
    addSection(file, kHoldoutZstd, false, w);
  } else if (!btf.holdoutImages.empty()) {
    ByteWriter w;
    w.u32(static_cast<std::uint32_t>(btf.holdoutImages.size()));
    for (int h : btf.holdoutImages) w.u32(static_cast<std::uint32_t>(h));
    addSection(file, kHoldout, false, w);
  }
  if (!btf.encoderState.empty()) {
    ByteWriter w;
    w.raw(btf.encoderState.data(), btf.encoderState.size());
    addSection(file, kEncoder, false, w);
  }
  if (btf.storage.metadataZstd) {
    // u32 size of the JSON text, a zstd frame of it.
    ByteWriter w;
    w.u32(static_cast<std::uint32_t>(btf.metadataJson.size()));
    auto coded = zstdCompress(reinterpret_cast<const std::uint8_t*>(btf.metadataJson.data()), btf.metadataJson.size());
    w.raw(coded.data(), coded.size());
    addSection(file, kMetaZstd, false, w);
  } else {
    ByteWriter w;
    w.raw(btf.metadataJson.data(), btf.metadataJson.size());
    addSection(file, kMeta, false, w);
  }

  auto& bytes = file.bytes();
  file.patchU64(16, bytes.size());
  file.patchU32(24, crc32(bytes.data() + kHeaderSize, bytes.size() - kHeaderSize));
  file.patchU32(kHeaderCrcOffset, crc32(bytes.data(), kHeaderCrcOffset));
  return std::move(bytes);
}

std::size_t writeNbtf(const std::string& path, const CompressedBtf& btf) {
  std::vector<std::uint8_t> bytes;
  try {
    bytes = serializeNbtf(btf);
  } catch (const Error& e) {
    throw fileError(path, std::string("refusing to write an invalid compressed BTF: ") + e.what());
  }
  writeFileAtomic(path, bytes.data(), bytes.size());
  return bytes.size();
}

// ---- Reading

namespace {

struct SectionRef {
  std::uint32_t tag = 0;
  std::uint32_t flags = 0;
  std::size_t offset = 0;  // of the section header
  const std::uint8_t* payload = nullptr;
  std::size_t size = 0;
  std::uint32_t crc = 0;
};

// Walks the section headers of [kHeaderSize, size). Throws on any structural problem.
std::vector<SectionRef> listSections(const std::uint8_t* data, std::size_t size, const std::string& name) {
  std::vector<SectionRef> sections;
  std::size_t pos = kHeaderSize;
  while (pos < size) {
    ByteReader r(data + pos, size - pos, name, "section header", pos);
    if (r.remaining() < kSectionHeaderSize)
      throw r.fail("truncated: " + std::to_string(r.remaining()) + " bytes left, a section header needs " +
                   std::to_string(kSectionHeaderSize));
    SectionRef s;
    s.offset = pos;
    s.tag = r.u32();
    s.flags = r.u32();
    std::uint64_t payloadSize = r.u64();
    s.crc = r.u32();
    r.u32();  // reserved
    std::uint64_t padded = payloadSize + (kAlign - payloadSize % kAlign) % kAlign;
    if (payloadSize > r.remaining() || padded > r.remaining())
      throw fileError(name, sectionLabel(s.tag) + " at offset " + std::to_string(pos) + " declares " +
                                std::to_string(payloadSize) + " bytes, but only " + std::to_string(r.remaining()) +
                                " remain in the file (truncated or corrupted)");
    s.size = static_cast<std::size_t>(payloadSize);
    s.payload = r.take(s.size, "payload");
    const std::uint8_t* pad = r.take(static_cast<std::size_t>(padded - payloadSize), "padding");
    for (std::size_t i = 0; i < padded - payloadSize; ++i)
      if (pad[i] != 0) throw fileError(name, sectionLabel(s.tag) + ": non-zero padding bytes (corrupted)");
    sections.push_back(s);
    pos += kSectionHeaderSize + static_cast<std::size_t>(padded);
  }
  return sections;
}

// For the error message of a failed body checksum: which section is damaged, if the
// section structure is still readable.
std::string locateDamage(const std::uint8_t* data, std::size_t size, const std::string& name) {
  try {
    for (const SectionRef& s : listSections(data, size, name))
      if (crc32(s.payload, s.size) != s.crc)
        return "; damaged: " + sectionLabel(s.tag) + " at offset " + std::to_string(s.offset);
    return "; the damage is in a section header or padding";
  } catch (const Error&) {
    return "; the section structure itself is damaged";
  }
}

std::vector<float> readFloats(ByteReader& r, std::uint64_t count, const char* field) {
  r.needItems(count, 4, field);
  std::vector<float> v(static_cast<std::size_t>(count));
  for (float& x : v) x = r.f32();
  return v;
}

int checkedInt(ByteReader& r, std::uint32_t v, std::uint32_t maxValue, const char* field) {
  if (v > maxValue)
    throw r.fail(std::string(field) + " = " + std::to_string(v) + " exceeds the limit " + std::to_string(maxValue));
  return static_cast<int>(v);
}

void parseInfo(const SectionRef& s, CompressedBtf& btf, const std::string& name) {
  ByteReader r(s.payload, s.size, name, sectionLabel(s.tag), s.offset + kSectionHeaderSize);
  btf.method = static_cast<CodecMethod>(r.u8());
  btf.directionEncoding = static_cast<DirectionEncoding>(r.u8());
  btf.valueSpace = static_cast<ValueSpace>(r.u8());
  std::uint8_t layout = r.u8();
  if (layout > 3) throw r.fail("unknown layout code " + std::to_string(layout));
  btf.layout = layoutFromCode(layout);
  std::uint8_t sampleType = r.u8();
  if (sampleType != 1 && sampleType != 2) throw r.fail("unknown sample type code " + std::to_string(sampleType));
  btf.sourceSampleType = sampleType == 1 ? SampleType::Srgb8 : SampleType::Half;
  r.take(3, "reserved");
  btf.width = checkedInt(r, r.u32(), kMaxSide, "width");
  btf.height = checkedInt(r, r.u32(), kMaxSide, "height");
  btf.sourceWidth = checkedInt(r, r.u32(), kMaxSide, "source width");
  btf.sourceHeight = checkedInt(r, r.u32(), kMaxSide, "source height");
  btf.crop.x = checkedInt(r, r.u32(), kMaxSide, "crop x");
  btf.crop.y = checkedInt(r, r.u32(), kMaxSide, "crop y");
  btf.crop.width = checkedInt(r, r.u32(), kMaxSide, "crop width");
  btf.crop.height = checkedInt(r, r.u32(), kMaxSide, "crop height");
  btf.alpha = r.f32();
  if (btf.method == CodecMethod::Pca) btf.latentDim = checkedInt(r, r.u32(), kMaxPcaComponents, "PCA components");
  else btf.latentDim = checkedInt(r, r.u32(), kMaxLatentDim, "latent dimension");
  btf.latentRows = checkedInt(r, r.u32(), INT_MAX, "latent rows");
  r.u32();  // reserved; fields appended by later minor versions follow and are ignored
}

void readDirectionPairs(ByteReader& r, std::uint64_t lights, std::uint64_t views, CompressedBtf& btf) {
  r.needItems(lights + views, 16, "direction count");
  btf.lights.resize(static_cast<std::size_t>(lights));
  btf.views.resize(static_cast<std::size_t>(views));
  for (auto* set : {&btf.lights, &btf.views})
    for (Direction& d : *set) {
      d.thetaDeg = r.f64();
      d.phiDeg = r.f64();
    }
  if (r.remaining()) throw r.fail(std::to_string(r.remaining()) + " unexpected bytes after the directions");
}

void parseDirections(const SectionRef& s, CompressedBtf& btf, const std::string& name) {
  ByteReader r(s.payload, s.size, name, sectionLabel(s.tag), s.offset + kSectionHeaderSize);
  std::uint64_t lights = r.u32(), views = r.u32();
  if (s.tag == kDirs) return readDirectionPairs(r, lights, views, btf);
  // DIRZ: the counts bound the frame's size before anything is allocated.
  if (lights > kMaxDirections || views > kMaxDirections)
    throw r.fail(std::to_string(lights) + " lights and " + std::to_string(views) + " views, at most " +
                 std::to_string(kMaxDirections) + " each");
  const std::size_t rest = r.remaining();
  auto planes = zstdDecompress(r.take(rest, "directions"), rest, static_cast<std::size_t>(lights + views) * 16, name,
                               sectionLabel(s.tag));
  const std::vector<std::uint8_t> pairs = bytesFromPlanes(planes, 8);
  ByteReader pr(pairs.data(), pairs.size(), name, sectionLabel(s.tag), s.offset + kSectionHeaderSize + 8);
  readDirectionPairs(pr, lights, views, btf);
  btf.storage.directionsZstd = true;
}

std::vector<float> readValues(ByteReader& r, std::uint64_t count, bool half, const char* field) {
  if (!half) return readFloats(r, count, field);
  r.needItems(count, 2, field);
  std::vector<float> v(static_cast<std::size_t>(count));
  for (float& x : v) x = halfToFloat(r.u16());
  return v;
}

void parsePlanes(const SectionRef& s, CompressedBtf& btf, const std::string& name) {
  ByteReader r(s.payload, s.size, name, sectionLabel(s.tag), s.offset + kSectionHeaderSize);
  DirectionPlanes& p = btf.planes;
  p.resolution = checkedInt(r, r.u32(), DirectionPlanes::kMaxResolution, "plane resolution");
  p.features = checkedInt(r, r.u32(), DirectionPlanes::kMaxFeatures, "plane features");
  if (p.resolution < 2 || p.features < 1)
    throw r.fail("direction planes of " + std::to_string(p.resolution) + " points x " + std::to_string(p.features) +
                 " features (at least 2 points and 1 feature)");
  const std::uint8_t half = r.u8();
  if (half > 1) throw r.fail("unknown plane value type " + std::to_string(half));
  r.take(3, "reserved");
  p.values = readValues(r, p.valueCount(), half == 1, "plane values");
}

void parseDecoder(const SectionRef& s, CompressedBtf& btf, const std::string& name) {
  const bool int8 = s.tag == kDecoderInt8, half = s.tag == kDecoderHalf;
  btf.storage.decoderHalf = half;
  btf.storage.decoderInt8 = int8;
  ByteReader r(s.payload, s.size, name, sectionLabel(s.tag), s.offset + kSectionHeaderSize);
  std::uint32_t count = r.u32();
  if (count < 1 || count > kMaxLayers) throw r.fail("layer count " + std::to_string(count) + " is out of range");
  r.needItems(count, 12, "layer count");
  btf.decoder.layers.resize(count);
  for (std::uint32_t i = 0; i < count; ++i) {
    DenseLayer& l = btf.decoder.layers[i];
    l.in = checkedInt(r, r.u32(), kMaxLayerWidth, "layer inputs");
    l.out = checkedInt(r, r.u32(), kMaxLayerWidth, "layer outputs");
    std::uint8_t act = r.u8();
    if (act > 2) throw r.fail("layer " + std::to_string(i) + " has unknown activation code " + std::to_string(act));
    l.activation = static_cast<Activation>(act);
    r.take(3, "reserved");
    const std::uint64_t weights = static_cast<std::uint64_t>(l.in) * static_cast<std::uint64_t>(l.out);
    if (int8) {
      const std::vector<float> scales = readValues(r, static_cast<std::uint64_t>(l.out), true, "row scales");
      r.needItems(weights, 1, "layer weights");
      l.weight.resize(static_cast<std::size_t>(weights));
      for (int o = 0; o < l.out; ++o) {
        const float scale = scales[o];
        if (!(scale >= kMinInt8Scale) || !std::isfinite(scale))
          throw r.fail("layer " + std::to_string(i) + " row " + std::to_string(o) + ": scale " + std::to_string(scale) +
                       " is not a finite half value >= 2^-14");
        int largest = 0;
        for (int c = 0; c < l.in; ++c) {
          const int code = static_cast<std::int8_t>(r.u8());
          if (code == -128) throw r.fail("layer " + std::to_string(i) + " row " + std::to_string(o) + ": code -128 (codes are -127..127)");
          largest = std::max(largest, std::abs(code));
          l.weight[static_cast<std::size_t>(o) * l.in + c] = static_cast<float>(code) * scale;
        }
        // The writer's scale is the smallest that fits the row: its largest code is 127.
        if (largest != 127 && scale != kMinInt8Scale)
          throw r.fail("layer " + std::to_string(i) + " row " + std::to_string(o) + ": largest code " +
                       std::to_string(largest) + ", expected 127 for scale " + std::to_string(scale));
      }
      l.bias = readValues(r, static_cast<std::uint64_t>(l.out), true, "layer biases");
    } else {
      l.weight = readValues(r, weights, half, "layer weights");
      l.bias = readValues(r, static_cast<std::uint64_t>(l.out), half, "layer biases");
    }
  }
  if (r.remaining()) throw r.fail(std::to_string(r.remaining()) + " unexpected bytes after the last layer");
}

void parseLatents(const SectionRef& s, CompressedBtf& btf, const std::string& name) {
  ByteReader r(s.payload, s.size, name, sectionLabel(s.tag), s.offset + kSectionHeaderSize);
  int rows = checkedInt(r, r.u32(), INT_MAX, "rows");
  int dim = checkedInt(r, r.u32(), kMaxLatentDim, "latent dimension");
  if (rows != btf.latentRows || dim != btf.latentDim)
    throw r.fail("shape " + std::to_string(rows) + " x " + std::to_string(dim) + " disagrees with the material info (" +
                 std::to_string(btf.latentRows) + " x " + std::to_string(btf.latentDim) + ")");
  const bool half = s.tag == kLatentsHalf;
  btf.storage.latentsHalf = half;
  const std::uint64_t bytes = half ? 2 : 4;
  std::uint64_t count = static_cast<std::uint64_t>(rows) * static_cast<std::uint64_t>(dim);
  if (count * bytes != r.remaining())
    throw r.fail("holds " + std::to_string(r.remaining()) + " bytes of values, expected " + std::to_string(count * bytes));
  btf.latents = readValues(r, count, half, "latents");
}

// TXIZ: u32 count, u8 width, u8 coding (1), 2 reserved, a zstd frame of width byte planes.
void parseIdsZstd(const SectionRef& s, CompressedBtf& btf, const std::string& name) {
  ByteReader r(s.payload, s.size, name, sectionLabel(s.tag), s.offset + kSectionHeaderSize);
  std::uint32_t count = r.u32();
  std::uint8_t width = r.u8(), coding = r.u8();
  r.take(2, "reserved");
  if (width != 1 && width != 2 && width != 4) throw r.fail("id width " + std::to_string(width) + " is not 1, 2 or 4");
  if (coding != 1) throw r.fail("unknown id coding " + std::to_string(coding) + " (1 = zstd)");
  // The count is bounded by the texels of INFO before anything is allocated.
  if (static_cast<std::int64_t>(count) != static_cast<std::int64_t>(btf.width) * btf.height)
    throw r.fail(std::to_string(count) + " ids for " + std::to_string(btf.width) + " x " + std::to_string(btf.height) +
                 " texels");
  const std::size_t rest = r.remaining();
  auto planes = zstdDecompress(r.take(rest, "id data"), rest, static_cast<std::size_t>(count) * width, name,
                               sectionLabel(s.tag));
  const std::vector<std::uint32_t> ids = fromBytePlanes(planes, count, width);
  btf.ids.resize(count);
  for (std::size_t t = 0; t < count; ++t) {
    if (ids[t] > static_cast<std::uint32_t>(INT_MAX)) throw r.fail("id " + std::to_string(ids[t]) + " is out of range");
    btf.ids[t] = static_cast<std::int32_t>(ids[t]);
  }
  btf.storage.idsZstd = true;
}

// TXSC: see the writer.
void parseModulation(const SectionRef& s, CompressedBtf& btf, const std::string& name) {
  ByteReader r(s.payload, s.size, name, sectionLabel(s.tag), s.offset + kSectionHeaderSize);
  std::uint32_t texels = r.u32();
  int terms = r.u8(), bits = r.u8(), coding = r.u8();
  int channels = 1;
  if (s.tag == kModulationRgb) {
    channels = r.u8();
    if (channels != 3) throw r.fail(std::to_string(channels) + " channels, expected 3");
  } else {
    r.take(1, "reserved");
  }
  if (terms < 1 || terms > kMaxModulationTerms)
    throw r.fail(std::to_string(terms) + " terms, expected 1 to " + std::to_string(kMaxModulationTerms));
  if (bits < 1 || bits > 16) throw r.fail(std::to_string(bits) + " bits per code, expected 1 to 16");
  if (coding > 1) throw r.fail("unknown coding " + std::to_string(coding) + " (0 raw, 1 zstd)");
  if (static_cast<std::int64_t>(texels) != static_cast<std::int64_t>(btf.width) * btf.height)
    throw r.fail(std::to_string(texels) + " texels, the material has " + std::to_string(btf.width) + " x " +
                 std::to_string(btf.height));
  TexelModulation& m = btf.modulation;
  m.terms = terms;
  m.channels = channels;
  m.bits = bits;
  const int columns = m.columns();
  for (int t = 0; t < columns; ++t) {
    m.minimum[t] = r.f32();
    m.maximum[t] = r.f32();
  }
  const int width = modulationCodeBytes(bits);
  const std::size_t values = static_cast<std::size_t>(texels) * columns, expected = values * width;
  const std::size_t rest = r.remaining();
  const std::uint8_t* data = r.take(rest, "codes");
  std::vector<std::uint8_t> planes;
  if (coding == 1) {
    planes = zstdDecompress(data, rest, expected, name, sectionLabel(s.tag));
  } else {
    if (rest != expected)
      throw r.fail("holds " + std::to_string(rest) + " bytes of codes, expected " + std::to_string(expected));
    planes.assign(data, data + rest);
  }
  const std::vector<std::uint32_t> byTerm = fromBytePlanes(planes, values, width);
  m.codes.resize(values);
  for (int q = 0; q < columns; ++q)
    for (std::size_t t = 0; t < texels; ++t) m.codes[t * columns + q] = static_cast<std::uint16_t>(byTerm[q * texels + t]);
  btf.storage.modulationZstd = coding == 1;
}

void parseIds(const SectionRef& s, CompressedBtf& btf, const std::string& name) {
  ByteReader r(s.payload, s.size, name, sectionLabel(s.tag), s.offset + kSectionHeaderSize);
  std::uint32_t count = r.u32();
  std::uint8_t width = r.u8();
  r.take(3, "reserved");
  if (width != 1 && width != 2 && width != 4) throw r.fail("id width " + std::to_string(width) + " is not 1, 2 or 4");
  if (static_cast<std::uint64_t>(count) * width != r.remaining())
    throw r.fail(std::to_string(count) + " ids of " + std::to_string(width) + " bytes need " +
                 std::to_string(static_cast<std::uint64_t>(count) * width) + " bytes, the section holds " +
                 std::to_string(r.remaining()));
  btf.ids.resize(count);
  for (auto& id : btf.ids) {
    std::uint32_t v = width == 1 ? r.u8() : width == 2 ? r.u16() : r.u32();
    if (v > static_cast<std::uint32_t>(INT_MAX)) throw r.fail("id " + std::to_string(v) + " is out of range");
    id = static_cast<std::int32_t>(v);
  }
}

// PCAM: u32 count, count f32. The count is checked against the bytes present before any
// allocation; its agreement with the directions is checked by validate().
void parsePcaMean(const SectionRef& s, CompressedBtf& btf, const std::string& name) {
  ByteReader r(s.payload, s.size, name, sectionLabel(s.tag), s.offset + kSectionHeaderSize);
  std::uint64_t count = r.u32();
  if (count * 4 != r.remaining())
    throw r.fail(std::to_string(count) + " values need " + std::to_string(count * 4) + " bytes, the section holds " +
                 std::to_string(r.remaining()));
  btf.pcaMean = readFloats(r, count, "PCA mean");
}

// PCAB and PCAC: u32 rows, u32 components (= INFO's), rows x components f32.
std::vector<float> parsePcaMatrix(const SectionRef& s, const CompressedBtf& btf, const std::string& name,
                                  const char* rowsName, std::uint64_t& rowsOut) {
  ByteReader r(s.payload, s.size, name, sectionLabel(s.tag), s.offset + kSectionHeaderSize);
  std::uint64_t rows = r.u32();
  std::uint64_t components = checkedInt(r, r.u32(), kMaxPcaComponents, "components");
  if (components != static_cast<std::uint64_t>(btf.latentDim))
    throw r.fail(std::to_string(components) + " components disagree with the material info (" +
                 std::to_string(btf.latentDim) + ")");
  const std::uint64_t count = rows * components;
  if (count * 4 != r.remaining())
    throw r.fail(std::to_string(rows) + " " + rowsName + " x " + std::to_string(components) + " components need " +
                 std::to_string(count * 4) + " bytes, the section holds " + std::to_string(r.remaining()));
  rowsOut = rows;
  return readFloats(r, count, "values");
}

void parseHoldout(const SectionRef& s, CompressedBtf& btf, const std::string& name) {
  ByteReader r(s.payload, s.size, name, sectionLabel(s.tag), s.offset + kSectionHeaderSize);
  std::uint32_t count = r.u32();
  if (static_cast<std::uint64_t>(count) * 4 != r.remaining())
    throw r.fail(std::to_string(count) + " indices need " + std::to_string(static_cast<std::uint64_t>(count) * 4) +
                 " bytes, the section holds " + std::to_string(r.remaining()));
  btf.holdoutImages.resize(count);
  for (int& h : btf.holdoutImages) h = checkedInt(r, r.u32(), INT_MAX, "hold-out image index");
}

// HOLZ: see the writer. Follows DIRS, so the image count is known.
void parseHoldoutZstd(const SectionRef& s, CompressedBtf& btf, const std::string& name) {
  ByteReader r(s.payload, s.size, name, sectionLabel(s.tag), s.offset + kSectionHeaderSize);
  std::uint32_t count = r.u32(), images = r.u32();
  if (static_cast<std::int64_t>(images) != btf.numImages())
    throw r.fail("a mask of " + std::to_string(images) + " images, the material has " +
                 std::to_string(btf.numImages()) + " (directions section)");
  const std::size_t rest = r.remaining();
  auto mask = zstdDecompress(r.take(rest, "mask"), rest, (static_cast<std::size_t>(images) + 7) / 8, name,
                             sectionLabel(s.tag));
  btf.holdoutImages.clear();
  for (std::uint32_t i = 0; i < images; ++i)
    if (mask[i / 8] >> (i % 8) & 1u) btf.holdoutImages.push_back(static_cast<int>(i));
  if (images % 8 && mask.back() >> (images % 8)) throw r.fail("the mask has bits set past the last image");
  if (btf.holdoutImages.size() != count)
    throw r.fail("the mask holds " + std::to_string(btf.holdoutImages.size()) + " images, the section says " +
                 std::to_string(count));
  btf.storage.metadataZstd = true;
}

// METZ: u32 size, a zstd frame of the JSON text.
void parseMetadataZstd(const SectionRef& s, CompressedBtf& btf, const std::string& name) {
  ByteReader r(s.payload, s.size, name, sectionLabel(s.tag), s.offset + kSectionHeaderSize);
  std::uint32_t size = r.u32();
  if (size > kMaxMetadataBytes)
    throw r.fail(std::to_string(size) + " bytes of metadata, more than the " + std::to_string(kMaxMetadataBytes) +
                 " allowed");
  const std::size_t rest = r.remaining();
  auto text = zstdDecompress(r.take(rest, "metadata"), rest, size, name, sectionLabel(s.tag));
  btf.metadataJson.assign(text.begin(), text.end());
  btf.storage.metadataZstd = true;
}

}  // namespace

CompressedBtf parseNbtf(const std::uint8_t* data, std::size_t size, const std::string& name,
                        const NbtfParseOptions& options) {
  // ---- Header: magic, version, size, checksums
  bool magicPrefix = std::equal(data, data + std::min(size, sizeof kNbtfMagic), kNbtfMagic);
  if (!magicPrefix) throw fileError(name, "not an .nbtf file (wrong magic bytes at the start)");
  if (size < kHeaderSize)
    throw fileError(name, "truncated: " + std::to_string(size) + " bytes, shorter than the " +
                              std::to_string(kHeaderSize) + "-byte .nbtf header");
  ByteReader h(data, kHeaderSize, name, "header");
  h.take(sizeof kNbtfMagic, "magic");
  std::uint16_t major = h.u16(), minor = h.u16();
  h.u32();  // flags: none defined in major version 1; ignored so minor versions may add some
  std::uint64_t declaredSize = h.u64();
  std::uint32_t bodyCrc = h.u32(), headerCrc = h.u32();
  if (options.verifyChecksums && crc32(data, kHeaderCrcOffset) != headerCrc)
    throw fileError(name, "corrupted: header checksum mismatch (stored " + hex32(headerCrc) + ", computed " +
                              hex32(crc32(data, kHeaderCrcOffset)) + ")");
  std::string version = std::to_string(major) + "." + std::to_string(minor);
  if (major > kNbtfFormatMajor)
    throw fileError(name, "format version " + version + " is newer than this nbtf can read (" +
                              std::to_string(kNbtfFormatMajor) + ".x); update nbtf");
  if (major < 1) throw fileError(name, "invalid format version " + version);
  if (declaredSize > size)
    throw fileError(name, "truncated: the header declares " + std::to_string(declaredSize) + " bytes, the file has " +
                              std::to_string(size) + " (" + std::to_string(declaredSize - size) + " missing)");
  if (declaredSize < size)
    throw fileError(name, std::to_string(size - declaredSize) + " unexpected bytes after the end of the data (the header declares " +
                              std::to_string(declaredSize) + " bytes)");
  if (declaredSize < kHeaderSize) throw fileError(name, "corrupted: declared size is smaller than the header");
  if (options.verifyChecksums) {
    std::uint32_t computed = crc32(data + kHeaderSize, size - kHeaderSize);
    if (computed != bodyCrc)
      throw fileError(name, "corrupted: checksum mismatch (CRC-32 stored " + hex32(bodyCrc) + ", computed " +
                                hex32(computed) + ")" + locateDamage(data, size, name));
  }

  // ---- Sections
  std::vector<SectionRef> sections = listSections(data, size, name);
  if (sections.empty() || sections.front().tag != kInfo)
    throw fileError(name, "corrupted: the first section must be 'INFO' (material info)");
  CompressedBtf btf;
  btf.formatMajor = major;
  btf.formatMinor = minor;
  btf.metadataJson.clear();
  std::vector<std::uint32_t> seen;
  for (const SectionRef& s : sections) {
    if (std::find(seen.begin(), seen.end(), s.tag) != seen.end())
      throw fileError(name, sectionLabel(s.tag) + " appears twice (offset " + std::to_string(s.offset) + ")");
    seen.push_back(s.tag);
    if (options.verifyChecksums && crc32(s.payload, s.size) != s.crc)
      throw fileError(name, "corrupted: checksum mismatch in " + sectionLabel(s.tag) + " at offset " +
                                std::to_string(s.offset));
    if (s.tag == kInfo) parseInfo(s, btf, name);
    else if (s.tag == kDirs || s.tag == kDirsZstd) parseDirections(s, btf, name);
    else if (s.tag == kDecoder || s.tag == kDecoderHalf || s.tag == kDecoderInt8) parseDecoder(s, btf, name);
    else if (s.tag == kPlanes) parsePlanes(s, btf, name);
    else if (s.tag == kLatents || s.tag == kLatentsHalf) parseLatents(s, btf, name);
    else if (s.tag == kIds) parseIds(s, btf, name);
    else if (s.tag == kIdsZstd) parseIdsZstd(s, btf, name);
    else if (s.tag == kModulation || s.tag == kModulationRgb) parseModulation(s, btf, name);
    else if (s.tag == kHoldout) parseHoldout(s, btf, name);
    else if (s.tag == kHoldoutZstd) parseHoldoutZstd(s, btf, name);
    else if (s.tag == kMetaZstd) parseMetadataZstd(s, btf, name);
    else if (s.tag == kPcaMean) parsePcaMean(s, btf, name);
    else if (s.tag == kPcaBasis) {
      std::uint64_t rows = 0;
      btf.pcaBasis = parsePcaMatrix(s, btf, name, "rows", rows);
    } else if (s.tag == kPcaCoefficients) {
      std::uint64_t rows = 0;
      btf.latents = parsePcaMatrix(s, btf, name, "texels", rows);
      if (rows != static_cast<std::uint64_t>(btf.latentRows))
        throw fileError(name, sectionLabel(s.tag) + ": " + std::to_string(rows) +
                                  " texels disagree with the material info (" + std::to_string(btf.latentRows) + ")");
    }
    else if (s.tag == kEncoder) btf.encoderState.assign(s.payload, s.payload + s.size);
    else if (s.tag == kMeta) btf.metadataJson.assign(reinterpret_cast<const char*>(s.payload), s.size);
    else if (s.flags & kSectionRequired)
      throw fileError(name, "required " + sectionLabel(s.tag) + " is unknown to this nbtf (format " + version +
                                "; written by a newer nbtf?); update nbtf");
    else
      btf.skippedSections.push_back(tagText(s.tag));
  }
  auto has = [&](std::uint32_t t) { return std::find(seen.begin(), seen.end(), t) != seen.end(); };
  if (!has(kDirs) && !has(kDirsZstd)) throw fileError(name, "missing " + sectionLabel(kDirs));
  // Alternative encodings of one part (float32 or half, raw or zstd): exactly one of a pair.
  for (auto pair : {std::make_pair(kDecoder, kDecoderHalf), std::make_pair(kDecoder, kDecoderInt8),
                    std::make_pair(kDecoderHalf, kDecoderInt8), std::make_pair(kLatents, kLatentsHalf),
                    std::make_pair(kIds, kIdsZstd), std::make_pair(kMeta, kMetaZstd), std::make_pair(kDirs, kDirsZstd),
                    std::make_pair(kHoldout, kHoldoutZstd), std::make_pair(kModulation, kModulationRgb)})
    if (has(pair.first) && has(pair.second))
      throw fileError(name, "both " + sectionLabel(pair.first) + " and " + sectionLabel(pair.second) + " present");
  auto hasPart = [&](std::uint32_t t) {
    return has(t) || (t == kDecoder && (has(kDecoderHalf) || has(kDecoderInt8))) || (t == kLatents && has(kLatentsHalf)) ||
           (t == kIds && has(kIdsZstd));
  };
  const bool pca = btf.method == CodecMethod::Pca;
  for (std::uint32_t t : {kDecoder, kLatents, kPcaMean, kPcaBasis, kPcaCoefficients}) {
    const bool pcaPart = t == kPcaMean || t == kPcaBasis || t == kPcaCoefficients;
    if (pcaPart == pca && !hasPart(t))
      throw fileError(name, "missing " + sectionLabel(t) + (pca ? " (required by the PCA method)" : ""));
    if (pcaPart != pca && hasPart(t))
      throw fileError(name, sectionLabel(t) + " present, but the method is " + codecMethodName(btf.method));
  }
  if (btf.method == CodecMethod::ClusteredNeural && !hasPart(kIds))
    throw fileError(name, "missing " + sectionLabel(kIds) + " (required by the clustered method)");
  if (btf.method != CodecMethod::ClusteredNeural && hasPart(kIds))
    throw fileError(name, sectionLabel(kIds) + " present, but the method is " + codecMethodName(btf.method));
  if (btf.method != CodecMethod::ClusteredNeural && (has(kModulation) || has(kModulationRgb)))
    throw fileError(name, sectionLabel(has(kModulation) ? kModulation : kModulationRgb) + " present, but the method is " + codecMethodName(btf.method));
  if (!has(kMeta) && !has(kMetaZstd)) btf.metadataJson = "{}";
  btf.validate(name);
  return btf;
}

CompressedBtf readNbtf(const std::string& path) {
  std::vector<std::uint8_t> bytes = readFileBytes(path);
  return parseNbtf(bytes.data(), bytes.size(), path);
}

bool hasNbtfMagic(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  unsigned char head[sizeof kNbtfMagic] = {};
  if (!in.read(reinterpret_cast<char*>(head), sizeof head)) return false;
  return std::equal(head, head + sizeof head, kNbtfMagic);
}

}  // namespace nbtf
