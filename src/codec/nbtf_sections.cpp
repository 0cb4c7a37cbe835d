#include "codec/nbtf_sections.h"

#include <algorithm>
#include <climits>
#include <cmath>

#include "codec/methods/method.h"
#include "codec/nbtf_format.h"
#include "codec/part_checks.h"
#include "codec/zstd_codec.h"
#include "util/error.h"
#include "util/half.h"
#include "util/printable.h"
#include <cstdio>

namespace nbtf::format {
namespace {

constexpr std::uint32_t kInfo = tag("INFO"), kDirs = tag("DIRS"), kDirsZstd = tag("DIRZ"), kDecoder = tag("DECD"),
                        kDecoderHalf = tag("DECH"), kDecoderInt8 = tag("DEC8"), kLatentsHalf = tag("LATH"),
                        kModulationRgb = tag("TXCH"), kModulationDecorrelated = tag("TXCR");

// Stored enum codes: independent of the in-memory enums so those can change freely.
std::uint8_t layoutCode(Layout l) {
  return l == Layout::Ubo2003 ? 1 : l == Layout::Utia ? 2 : l == Layout::Ubo2014 ? 3 : 0;
}
Layout layoutFromCode(std::uint8_t c) {
  return c == 1 ? Layout::Ubo2003 : c == 2 ? Layout::Utia : c == 3 ? Layout::Ubo2014 : Layout::Unknown;
}
std::uint8_t sampleTypeCode(SampleType t) { return t == SampleType::Srgb8 ? 1 : 2; }

// ---- Writers: one per section, in the order of the table

void writeFloats(ByteWriter& w, const std::vector<float>& v) {
  for (float x : v) w.f32(x);
}
void writeValues(ByteWriter& w, const std::vector<float>& v, bool half) {
  if (!half) return writeFloats(w, v);
  for (float x : v) w.u16(floatToHalf(x));
}

void writeInfo(const CompressedBtf& btf, ByteWriter& w) {
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
}

// u32 lights, u32 views, then (f64 theta, f64 phi) per direction, lights first; DIRZ:
// those pairs as 8 byte planes in one zstd frame (regular grids leave most planes zero).
void writeDirections(const CompressedBtf& btf, ByteWriter& w) {
  ByteWriter pairs;
  for (const auto* set : {&btf.lights, &btf.views})
    for (const Direction& d : *set) {
      pairs.f64(d.thetaDeg);
      pairs.f64(d.phiDeg);
    }
  w.u32(static_cast<std::uint32_t>(btf.lights.size()));
  w.u32(static_cast<std::uint32_t>(btf.views.size()));
  if (btf.storage.directionsZstd) {
    auto planes = bytePlanesOf(pairs.bytes(), 8);
    auto coded = zstdCompress(planes.data(), planes.size());
    w.raw(coded.data(), coded.size());
  } else {
    w.raw(pairs.bytes().data(), pairs.size());
  }
}

// PCA's mean, basis and coefficients (docs/file_format.md): all required, so a 1.0 reader
// refuses the file by name instead of missing its decoder.
void writePcaMean(const CompressedBtf& btf, ByteWriter& w) {
  w.u32(static_cast<std::uint32_t>(btf.pcaMean.size()));
  writeFloats(w, btf.pcaMean);
}
void writePcaBasis(const CompressedBtf& btf, ByteWriter& w) {
  w.u32(static_cast<std::uint32_t>(btf.pcaMean.size()));
  w.u32(static_cast<std::uint32_t>(btf.latentDim));
  writeFloats(w, btf.pcaBasis);
}
void writePcaCoefficients(const CompressedBtf& btf, ByteWriter& w) {
  w.u32(static_cast<std::uint32_t>(btf.latentRows));
  w.u32(static_cast<std::uint32_t>(btf.latentDim));
  writeFloats(w, btf.latents);
}

// Per layer: u32 in, u32 out, u8 activation, 3 reserved, then float32 or half weights and
// biases; DEC8: out half scales, out x in signed 8-bit codes (weight = code x its row's
// scale), out half biases.
void writeDecoder(const CompressedBtf& btf, ByteWriter& w) {
  const bool int8 = btf.storage.decoderInt8;
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
}

// u32 resolution R, u32 features F, u8 1 = half values (0 = float32), 3 reserved, then
// 3 x R x R x F values: plane (light, view, half vector), row y, column x, feature.
void writePlanes(const CompressedBtf& btf, ByteWriter& w) {
  const bool half = storagePlanesHalf(btf);
  w.u32(static_cast<std::uint32_t>(btf.planes.resolution));
  w.u32(static_cast<std::uint32_t>(btf.planes.features));
  w.u8(half ? 1 : 0);
  w.zeros(3);
  writeValues(w, btf.planes.values, half);
}

// CPLN (format 1.9): u32 rows, u32 resolution R, u32 features F, u8 value type, 3 reserved,
// then rows x 3 x R x R x F values (row, then as in DPLN). Value type 0 = float32, 1 = half,
// 2 = 8-bit (format 1.10): first rows x F float32 pairs (lo, hi), row-major, then one code
// per value (clusterPlaneRanges).
void writeClusterPlanes(const CompressedBtf& btf, ByteWriter& w) {
  const RowPlanes& p = btf.clusterPlanes;
  const int bytes = format::clusterPlaneBytesPerValue(btf);
  w.u32(static_cast<std::uint32_t>(p.rows));
  w.u32(static_cast<std::uint32_t>(p.resolution));
  w.u32(static_cast<std::uint32_t>(p.features));
  w.u8(bytes == 1 ? 2 : bytes == 2 ? 1 : 0);
  w.zeros(3);
  if (bytes != 1) return writeValues(w, p.values, bytes == 2);
  const std::vector<float> ranges = format::clusterPlaneRanges(p);
  writeValues(w, ranges, false);
  for (std::uint8_t code : format::clusterPlaneCodes(p, ranges)) w.u8(code);
}

void writeLatents(const CompressedBtf& btf, ByteWriter& w) {
  w.u32(static_cast<std::uint32_t>(btf.latentRows));
  w.u32(static_cast<std::uint32_t>(btf.latentDim));
  writeValues(w, btf.latents, btf.storage.latentsHalf);
}

// TXID: u32 count, u8 width, 3 reserved, the ids in the smallest width that holds k.
void writeIds(const CompressedBtf& btf, ByteWriter& w) {
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
}

// TXIZ: u32 count, u8 width, u8 coding (1 = zstd over byte planes), 2 reserved, the frame.
void writeIdsZstd(const CompressedBtf& btf, ByteWriter& w) {
  w.u32(static_cast<std::uint32_t>(btf.ids.size()));
  w.u8(static_cast<std::uint8_t>(idWidthForClusters(btf.latentRows)));
  w.u8(1);
  w.zeros(2);
  auto coded = codedIds(btf);
  w.raw(coded.data(), coded.size());
}

// u32 texels, u8 terms, u8 bits, u8 coding (0 raw, 1 zstd), u8 channels (TXCH, TXCR: 3; TXSC:
// reserved, 0), columns x (f32 min, f32 max), TXCR only: terms x 9 f32 (each term's rotation,
// row-major), then the codes (codedModulation: byte planes of the column planes; TXCR zstd-coded:
// a frame per column). Per-channel and decorrelated coefficients get tags of their own, so
// that a reader before 1.5 (1.11) refuses them instead of misreading them.
void writeModulation(const CompressedBtf& btf, ByteWriter& w) {
  const TexelModulation& m = btf.modulation;
  const bool perChannel = m.channels != 1;
  w.u32(static_cast<std::uint32_t>(m.codes.size() / m.columns()));
  w.u8(static_cast<std::uint8_t>(m.terms));
  w.u8(static_cast<std::uint8_t>(m.bits));
  w.u8(btf.storage.modulationZstd ? 1 : 0);
  w.u8(perChannel ? static_cast<std::uint8_t>(m.channels) : 0);
  for (int r = 0; r < m.columns(); ++r) {
    w.f32(m.minimum[r]);
    w.f32(m.maximum[r]);
  }
  if (m.decorrelated)
    for (int i = 0; i < 9 * m.terms; ++i) w.f32(m.rotation[i]);
  auto coded = codedModulation(m, btf.storage.modulationZstd);
  w.raw(coded.data(), coded.size());
}

// HOLD: u32 count, the ascending image indices as u32.
void writeHoldout(const CompressedBtf& btf, ByteWriter& w) {
  w.u32(static_cast<std::uint32_t>(btf.holdoutImages.size()));
  for (int h : btf.holdoutImages) w.u32(static_cast<std::uint32_t>(h));
}

// HOLZ: u32 count, u32 images, a zstd frame of the images' bit mask (bit i of byte i / 8).
void writeHoldoutZstd(const CompressedBtf& btf, ByteWriter& w) {
  w.u32(static_cast<std::uint32_t>(btf.holdoutImages.size()));
  w.u32(static_cast<std::uint32_t>(btf.numImages()));
  std::vector<std::uint8_t> mask((static_cast<std::size_t>(btf.numImages()) + 7) / 8, 0);
  for (int h : btf.holdoutImages) mask[h / 8] |= static_cast<std::uint8_t>(1u << (h % 8));
  auto coded = zstdCompress(mask.data(), mask.size());
  w.raw(coded.data(), coded.size());
}

void writeEncoder(const CompressedBtf& btf, ByteWriter& w) { w.raw(btf.encoderState.data(), btf.encoderState.size()); }

void writeMetadata(const CompressedBtf& btf, ByteWriter& w) { w.raw(btf.metadataJson.data(), btf.metadataJson.size()); }

// METZ: u32 size of the JSON text, a zstd frame of it.
void writeMetadataZstd(const CompressedBtf& btf, ByteWriter& w) {
  w.u32(static_cast<std::uint32_t>(btf.metadataJson.size()));
  auto coded = zstdCompress(reinterpret_cast<const std::uint8_t*>(btf.metadataJson.data()), btf.metadataJson.size());
  w.raw(coded.data(), coded.size());
}

// ---- Readers
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

void parseClusterPlanes(const SectionRef& s, CompressedBtf& btf, const std::string& name) {
  ByteReader r(s.payload, s.size, name, sectionLabel(s.tag), s.offset + kSectionHeaderSize);
  RowPlanes& p = btf.clusterPlanes;
  p.rows = checkedInt(r, r.u32(), INT32_MAX, "cluster plane rows");
  p.resolution = checkedInt(r, r.u32(), DirectionPlanes::kMaxResolution, "cluster plane resolution");
  p.features = checkedInt(r, r.u32(), DirectionPlanes::kMaxFeatures, "cluster plane features");
  if (p.rows < 1 || p.resolution < 2 || p.features < 1)
    throw r.fail("cluster planes of " + std::to_string(p.rows) + " rows x " + std::to_string(p.resolution) +
                 " points x " + std::to_string(p.features) + " features (at least 1 row, 2 points and 1 feature)");
  const std::uint8_t type = r.u8();
  if (type > 2) throw r.fail("unknown cluster plane value type " + std::to_string(type));
  r.take(3, "reserved");
  btf.storage.clusterPlanes8Bit = type == 2;
  if (type < 2) {
    p.values = readValues(r, p.valueCount(), type == 1, "cluster plane values");
    return;
  }
  const std::vector<float> ranges =
      readValues(r, static_cast<std::size_t>(p.rows) * p.features * 2, false, "cluster plane ranges");
  for (std::size_t i = 0; i < ranges.size(); i += 2)
    if (!std::isfinite(ranges[i]) || !std::isfinite(ranges[i + 1]) || !(ranges[i] <= ranges[i + 1]))
      throw r.fail("cluster plane range " + std::to_string(i / 2) + " (row " + std::to_string(i / 2 / p.features) +
                   ", feature " + std::to_string(i / 2 % p.features) + ") is not a finite lo <= hi");
  r.needItems(p.valueCount(), 1, "cluster plane codes");
  p.values = format::clusterPlaneCodeValues(p, ranges, r.take(p.valueCount(), "cluster plane codes"));
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
  const bool decorrelated = s.tag == kModulationDecorrelated;
  if (s.tag == kModulationRgb || decorrelated) {
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
  m.decorrelated = decorrelated;
  if (decorrelated)
    for (int i = 0; i < 9 * terms; ++i) m.rotation[i] = r.f32();
  const int width = modulationCodeBytes(bits);
  const std::size_t values = static_cast<std::size_t>(texels) * columns, expected = values * width;
  std::vector<std::uint32_t> byTerm;
  if (coding == 1 && decorrelated) {  // a frame per column, after their sizes
    std::vector<std::uint32_t> sizes(columns);
    for (auto& size : sizes) size = r.u32();
    byTerm.reserve(values);
    for (int q = 0; q < columns; ++q) {
      const std::uint8_t* frame = r.take(sizes[q], "codes");
      const auto column = fromBytePlanes(
          zstdDecompress(frame, sizes[q], expected / columns, name, sectionLabel(s.tag)), texels, width);
      byTerm.insert(byTerm.end(), column.begin(), column.end());
    }
    if (r.remaining()) throw r.fail(std::to_string(r.remaining()) + " bytes after the last column's codes");
  } else {
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
    byTerm = fromBytePlanes(planes, values, width);
  }
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

void parsePcaBasis(const SectionRef& s, CompressedBtf& btf, const std::string& name) {
  std::uint64_t rows = 0;
  btf.pcaBasis = parsePcaMatrix(s, btf, name, "rows", rows);
}

void parsePcaCoefficients(const SectionRef& s, CompressedBtf& btf, const std::string& name) {
  std::uint64_t rows = 0;
  btf.latents = parsePcaMatrix(s, btf, name, "texels", rows);
  if (rows != static_cast<std::uint64_t>(btf.latentRows))
    throw fileError(name, sectionLabel(s.tag) + ": " + std::to_string(rows) +
                              " texels disagree with the material info (" + std::to_string(btf.latentRows) + ")");
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

void parseEncoder(const SectionRef& s, CompressedBtf& btf, const std::string&) {
  btf.encoderState.assign(s.payload, s.payload + s.size);
}

void parseMetadata(const SectionRef& s, CompressedBtf& btf, const std::string&) {
  btf.metadataJson.assign(reinterpret_cast<const char*>(s.payload), s.size);
}

// ---- Table-1 bytes of the parts as stored and as the paper stored them (computeSizes)

std::uint64_t texelCount(const CompressedBtf& b) { return static_cast<std::uint64_t>(std::max(b.numTexels(), 0)); }
std::uint64_t latentValues(const CompressedBtf& b) {
  return static_cast<std::uint64_t>(std::max(b.latentRows, 0)) * static_cast<std::uint64_t>(std::max(b.latentDim, 0));
}
std::uint64_t decoderParameters(const CompressedBtf& b) {
  std::uint64_t n = 0;
  for (const auto& layer : b.decoder.layers) n += layer.parameterCount();
  return n;
}
std::uint64_t decoderBytes(const CompressedBtf& b) {
  const int bytesPerValue = b.storage.decoderInt8 ? 1 : b.storage.decoderHalf ? 2 : 4;
  std::uint64_t bytes = decoderParameters(b) * bytesPerValue;
  if (b.storage.decoderInt8)  // 1-byte weights, a 2-byte scale and a 2-byte bias per output
    for (const auto& layer : b.decoder.layers) bytes += 3 * layer.bias.size();
  return bytes;
}
std::uint64_t planeBytes(const CompressedBtf& b) { return b.planes.valueCount() * (storagePlanesHalf(b) ? 2 : 4); }
std::uint64_t clusterPlaneBytes(const CompressedBtf& b) {
  const int bytes = format::clusterPlaneBytesPerValue(b);
  const std::uint64_t ranges = bytes == 1 ? static_cast<std::uint64_t>(b.clusterPlanes.rows) * b.clusterPlanes.features * 8 : 0;
  return b.clusterPlanes.valueCount() * bytes + ranges;  // 8-bit: a float32 range per row and feature
}
std::uint64_t latentBytes(const CompressedBtf& b) { return latentValues(b) * (b.storage.latentsHalf ? 2 : 4); }
std::uint64_t idBytes(const CompressedBtf& b) { return texelCount(b) * idWidthForClusters(b.latentRows); }
std::uint64_t idZstdBytes(const CompressedBtf& b) {
  return b.ids.size() == texelCount(b) ? codedIds(b).size() : idBytes(b);  // planning: no ids yet
}
std::uint64_t modulationBytes(const CompressedBtf& b) {
  return codedModulation(b.modulation, b.storage.modulationZstd).size();
}
// The paper's storage: float32 values, 4-byte ids.
std::uint64_t decoderPaperBytes(const CompressedBtf& b) { return decoderParameters(b) * 4; }
std::uint64_t planePaperBytes(const CompressedBtf& b) { return b.planes.valueCount() * 4; }
std::uint64_t clusterPlanePaperBytes(const CompressedBtf& b) { return b.clusterPlanes.valueCount() * 4; }
std::uint64_t latentPaperBytes(const CompressedBtf& b) { return latentValues(b) * 4; }
std::uint64_t idPaperBytes(const CompressedBtf& b) { return texelCount(b) * 4; }
std::uint64_t pcaComponents(const CompressedBtf& b) { return static_cast<std::uint64_t>(std::max(b.latentDim, 0)); }
std::uint64_t pcaMeanBytes(const CompressedBtf& b) { return static_cast<std::uint64_t>(b.numImages()) * 3 * 4; }
std::uint64_t pcaBasisBytes(const CompressedBtf& b) { return pcaMeanBytes(b) * pcaComponents(b); }
std::uint64_t pcaCoefficientBytes(const CompressedBtf& b) { return texelCount(b) * pcaComponents(b) * 4; }

// ---- Which encoding the writer picks

bool always(const CompressedBtf&) { return true; }
// Whether the material's kind stores the part at all (codec/methods/); the storage flags then
// pick its encoding.
bool stores(const CompressedBtf& b, Part part) {
  const MethodKind* kind = findMethodKind(b.method);
  return kind && kind->need(part) != Need::Forbidden;
}
const PartStorage& st(const CompressedBtf& b) { return b.storage; }

std::uint16_t infoMinor(const CompressedBtf& b) {
  switch (b.directionEncoding) {
    case DirectionEncoding::Stereographic: return 0;
    case DirectionEncoding::StereographicFourier: return 6;   // a reader before 1.6 refuses encoding 3 by name
    case DirectionEncoding::StereographicFourier2: return 7;  // and one before 1.7 encoding 4
    default: return 3;                                        // the encodings other than the paper's pair
  }
}

// A reader before 1.10 refuses value type 2 by name.
std::uint16_t clusterPlanesMinor(const CompressedBtf& b) { return b.storage.clusterPlanes8Bit ? 10 : 9; }

bool pcaMean(const CompressedBtf& b) { return stores(b, Part::PcaMean); }
bool pcaBasis(const CompressedBtf& b) { return stores(b, Part::PcaBasis); }
bool pcaCoefficients(const CompressedBtf& b) { return stores(b, Part::PcaCoefficients); }
bool storesDecoder(const CompressedBtf& b) { return stores(b, Part::Decoder); }
bool float32Decoder(const CompressedBtf& b) { return storesDecoder(b) && !st(b).decoderInt8 && !st(b).decoderHalf; }
bool halfDecoder(const CompressedBtf& b) { return storesDecoder(b) && !st(b).decoderInt8 && st(b).decoderHalf; }
bool int8Decoder(const CompressedBtf& b) { return storesDecoder(b) && st(b).decoderInt8; }
bool hasPlanes(const CompressedBtf& b) { return !b.planes.empty(); }
bool hasClusterPlanes(const CompressedBtf& b) { return !b.clusterPlanes.empty(); }
bool float32Latents(const CompressedBtf& b) { return stores(b, Part::Latents) && !st(b).latentsHalf; }
bool halfLatents(const CompressedBtf& b) { return stores(b, Part::Latents) && st(b).latentsHalf; }
bool rawIds(const CompressedBtf& b) { return stores(b, Part::Ids) && !st(b).idsZstd; }
bool zstdIds(const CompressedBtf& b) { return stores(b, Part::Ids) && st(b).idsZstd; }
bool sharedModulation(const CompressedBtf& b) { return !b.modulation.empty() && b.modulation.channels == 1; }
bool perChannelModulation(const CompressedBtf& b) {
  return !b.modulation.empty() && b.modulation.channels != 1 && !b.modulation.decorrelated;
}
bool decorrelatedModulation(const CompressedBtf& b) { return !b.modulation.empty() && b.modulation.decorrelated; }
bool rawDirections(const CompressedBtf& b) { return !st(b).directionsZstd; }
bool zstdDirections(const CompressedBtf& b) { return st(b).directionsZstd; }
bool rawHoldout(const CompressedBtf& b) { return !b.holdoutImages.empty() && !st(b).metadataZstd; }
bool zstdHoldout(const CompressedBtf& b) { return !b.holdoutImages.empty() && st(b).metadataZstd; }
bool hasEncoder(const CompressedBtf& b) { return !b.encoderState.empty(); }
bool rawMetadata(const CompressedBtf& b) { return !st(b).metadataZstd; }
bool zstdMetadata(const CompressedBtf& b) { return st(b).metadataZstd; }

// tag, label, part, required, minor, content minor, written, write, parse, Table-1 bytes.
// The order is the writer's; files written since format 1.0 keep it.
const std::vector<SectionKind> kSections = {
    {kInfo, "material info", Part::Info, true, 0, infoMinor, always, writeInfo, parseInfo, nullptr, nullptr},
    {kDirs, "directions", Part::Directions, true, 0, nullptr, rawDirections, writeDirections, parseDirections, nullptr, nullptr},
    {kDirsZstd, "directions, zstd-coded", Part::Directions, true, 4, nullptr, zstdDirections, writeDirections,
     parseDirections, nullptr, nullptr},
    {tag("PCAM"), "PCA mean", Part::PcaMean, true, 1, nullptr, pcaMean, writePcaMean, parsePcaMean, pcaMeanBytes, nullptr},
    {tag("PCAB"), "PCA basis", Part::PcaBasis, true, 1, nullptr, pcaBasis, writePcaBasis, parsePcaBasis, pcaBasisBytes, nullptr},
    {tag("PCAC"), "PCA coefficients", Part::PcaCoefficients, true, 1, nullptr, pcaCoefficients, writePcaCoefficients,
     parsePcaCoefficients, pcaCoefficientBytes, nullptr},
    {kDecoder, "decoder", Part::Decoder, true, 0, nullptr, float32Decoder, writeDecoder, parseDecoder, decoderBytes, decoderPaperBytes},
    {kDecoderHalf, "decoder, half precision", Part::Decoder, true, 2, nullptr, halfDecoder, writeDecoder, parseDecoder,
     decoderBytes, decoderPaperBytes},
    {kDecoderInt8, "decoder, 8-bit weights", Part::Decoder, true, 4, nullptr, int8Decoder, writeDecoder, parseDecoder,
     decoderBytes, decoderPaperBytes},
    {tag("DPLN"), "direction planes", Part::Planes, true, 8, nullptr, hasPlanes, writePlanes, parsePlanes, planeBytes, planePaperBytes},
    {tag("CPLN"), "cluster planes", Part::ClusterPlanes, true, 9, clusterPlanesMinor, hasClusterPlanes, writeClusterPlanes,
     parseClusterPlanes, clusterPlaneBytes, clusterPlanePaperBytes},
    {tag("LATN"), "latents", Part::Latents, true, 0, nullptr, float32Latents, writeLatents, parseLatents, latentBytes, latentPaperBytes},
    {kLatentsHalf, "latents, half precision", Part::Latents, true, 2, nullptr, halfLatents, writeLatents, parseLatents,
     latentBytes, latentPaperBytes},
    {tag("TXID"), "id list", Part::Ids, true, 0, nullptr, rawIds, writeIds, parseIds, idBytes, idPaperBytes},
    {tag("TXIZ"), "id list, zstd-coded", Part::Ids, true, 2, nullptr, zstdIds, writeIdsZstd, parseIdsZstd, idZstdBytes, idPaperBytes},
    {tag("TXSC"), "per-texel modulation", Part::Modulation, true, 2, nullptr, sharedModulation, writeModulation,
     parseModulation, modulationBytes, nullptr},
    {kModulationRgb, "per-texel modulation, per channel", Part::Modulation, true, 5, nullptr, perChannelModulation,
     writeModulation, parseModulation, modulationBytes, nullptr},
    {kModulationDecorrelated, "per-texel modulation, decorrelated", Part::Modulation, true, 11, nullptr,
     decorrelatedModulation, writeModulation, parseModulation, modulationBytes, nullptr},
    {tag("HOLD"), "hold-out images", Part::Holdout, false, 0, nullptr, rawHoldout, writeHoldout, parseHoldout, nullptr, nullptr},
    {tag("HOLZ"), "hold-out images, zstd-coded", Part::Holdout, false, 4, nullptr, zstdHoldout, writeHoldoutZstd,
     parseHoldoutZstd, nullptr, nullptr},
    {tag("ENCD"), "encoder", Part::Encoder, false, 0, nullptr, hasEncoder, writeEncoder, parseEncoder, nullptr, nullptr},
    {tag("META"), "metadata", Part::Metadata, false, 0, nullptr, rawMetadata, writeMetadata, parseMetadata, nullptr, nullptr},
    {tag("METZ"), "metadata, zstd-coded", Part::Metadata, false, 4, nullptr, zstdMetadata, writeMetadataZstd,
     parseMetadataZstd, nullptr, nullptr},
};

// ---- The size table's rows: what each part's bytes are made of (formatSizeTable)

std::string precisionNote(int bytes) { return bytes == 2 ? " x 2 bytes (half)" : " x 4 bytes (float32)"; }
std::string texelsText(const CompressedBtf& b) { return groupedDigits(texelCount(b)); }
std::string imagesText(const CompressedBtf& b) { return groupedDigits(static_cast<std::uint64_t>(b.numImages())); }

std::string decoderNote(const CompressedBtf& b) {
  return groupedDigits(decoderParameters(b)) + " parameters" +
         (st(b).decoderInt8 ? std::string(": 8-bit weights, half scale per row, half biases")
                            : precisionNote(st(b).decoderHalf ? 2 : 4));
}
std::string planesNote(const CompressedBtf& b) {
  const std::string r = std::to_string(b.planes.resolution);
  return "3 direction planes x " + r + " x " + r + " points x " + std::to_string(b.planes.features) + " features" +
         precisionNote(storagePlanesHalf(b) ? 2 : 4);
}
std::string clusterPlanesNote(const CompressedBtf& b) {
  const RowPlanes& p = b.clusterPlanes;
  const int bytes = format::clusterPlaneBytesPerValue(b);
  const std::string r = std::to_string(p.resolution);
  return groupedDigits(static_cast<std::uint64_t>(b.latentRows)) + " rows x 3 planes x " + r + " x " + r +
         " points x " + std::to_string(p.features) + " features" +
         (bytes == 1 ? std::string(": 8-bit codes, a float32 range per row and feature") : precisionNote(bytes));
}
std::string latentsNote(const CompressedBtf& b) {
  return groupedDigits(static_cast<std::uint64_t>(b.latentRows)) + " x " + std::to_string(b.latentDim) +
         precisionNote(st(b).latentsHalf ? 2 : 4);
}
std::string idsNote(const CompressedBtf& b) {
  const int width = idWidthForClusters(b.latentRows);
  const std::string bytes = std::to_string(width) + " byte" + (width > 1 ? "s" : "");
  if (!(st(b).idsZstd && b.ids.size() == texelCount(b)))  // raw, or planning (no ids yet)
    return texelsText(b) + " texels x " + bytes + " (smallest width that fits k; the paper used 4)";
  char bits[64];
  std::snprintf(bits, sizeof bits, "%.2f", texelCount(b) ? 8.0 * idZstdBytes(b) / texelCount(b) : 0.0);
  return texelsText(b) + " texels x " + bytes + ", zstd-coded (" + bits + " bits per texel)";
}
const char* idsAbsent(const CompressedBtf& b) {
  return b.method == CodecMethod::PerTexelNeural ? "none (per-texel: one latent per texel)" : nullptr;
}
std::string modulationNote(const CompressedBtf& b) {
  const TexelModulation& m = b.modulation;
  const int columns = m.columns();
  char note[200];
  std::snprintf(note, sizeof note, "%s texels x %d coefficient%s%s x %d-bit codes, %.2f bits per texel as stored",
                texelsText(b).c_str(), columns, columns > 1 ? "s" : "",
                m.decorrelated ? " (per RGB channel, decorrelated)" : m.channels > 1 ? " (per RGB channel)" : "", m.bits,
                texelCount(b) ? 8.0 * modulationBytes(b) / texelCount(b) : 0.0);
  return note;
}
std::string pcaMeanNote(const CompressedBtf& b) { return imagesText(b) + " images x 3 x 4 bytes"; }
std::string pcaBasisNote(const CompressedBtf& b) {
  return imagesText(b) + " images x 3 x " + std::to_string(b.latentDim) + " components x 4 bytes";
}
std::string pcaCoefficientsNote(const CompressedBtf& b) {
  return texelsText(b) + " texels x " + std::to_string(b.latentDim) + " components x 4 bytes";
}

const std::vector<PartRow> kPartRows = {
    {Part::Decoder, "decoder", "decoder", decoderNote, nullptr, checkDecoderPart},
    {Part::Planes, "planes", "planes", planesNote, nullptr, checkDirectionPlanesPart},
    {Part::ClusterPlanes, "cl. planes", "cluster planes", clusterPlanesNote, nullptr, checkClusterPlanesPart},
    {Part::Latents, "latents", "latents", latentsNote, nullptr, checkLatentsPart},
    {Part::Ids, "id list", "id list", idsNote, idsAbsent, checkIdsPart},
    {Part::Modulation, "per-texel", "per-texel", modulationNote, nullptr, checkModulationPart},
    {Part::PcaMean, "mean", "mean", pcaMeanNote, nullptr, checkPcaMeanPart},
    {Part::PcaBasis, "basis", "basis", pcaBasisNote, nullptr, checkPcaBasisPart},
    {Part::PcaCoefficients, "coefficients", "coefficients", pcaCoefficientsNote, nullptr, checkPcaCoefficientsPart},
};

}  // namespace

const std::vector<SectionKind>& sectionKinds() { return kSections; }

const SectionKind* findSectionKind(std::uint32_t t) {
  for (const SectionKind& k : kSections)
    if (k.tag == t) return &k;
  return nullptr;
}

const SectionKind* writtenSection(const CompressedBtf& btf, Part part) {
  for (const SectionKind& k : kSections)
    if (k.part == part && k.written(btf)) return &k;
  return nullptr;
}

std::uint64_t tableBytesWritten(const CompressedBtf& btf) {
  std::uint64_t total = 0;
  for (const SectionKind& k : kSections)
    if (k.tableBytes && k.written(btf)) total += k.tableBytes(btf);
  return total;
}

std::uint64_t paperBytesWritten(const CompressedBtf& btf) {
  std::uint64_t total = 0;
  for (const SectionKind& k : kSections)
    if (k.tableBytes && k.written(btf)) total += k.paperBytes ? k.paperBytes(btf) : k.tableBytes(btf);
  return total;
}

const std::vector<PartRow>& partRows() { return kPartRows; }

const std::vector<Part>& checkedParts() {
  static const std::vector<Part> parts = [] {
    std::vector<Part> p;
    for (int i = 0; i <= static_cast<int>(Part::Metadata); ++i) p.push_back(static_cast<Part>(i));
    return p;
  }();
  return parts;
}

std::uint32_t primaryTag(Part part) {
  for (const SectionKind& k : kSections)
    if (k.part == part) return k.tag;
  return 0;
}

std::string tagText(std::uint32_t t) {
  const unsigned char bytes[4] = {static_cast<unsigned char>(t), static_cast<unsigned char>(t >> 8),
                                  static_cast<unsigned char>(t >> 16), static_cast<unsigned char>(t >> 24)};
  return printableBytes(bytes, 4);
}

std::string sectionLabel(std::uint32_t t) {
  const SectionKind* k = findSectionKind(t);
  return "section '" + tagText(t) + "'" + (k ? std::string(" (") + k->label + ")" : std::string());
}

}  // namespace nbtf::format
