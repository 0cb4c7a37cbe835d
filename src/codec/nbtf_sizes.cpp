// Names and sizes of a compressed material: the Table-1 parts as stored, and their text.
#include <algorithm>
#include <cstdio>

#include "codec/nbtf_format.h"
#include "codec/nbtf_sections.h"

namespace nbtf {

using format::storagePlanesHalf;

int idWidthForClusters(std::int64_t k) {
  if (k <= 0x100) return 1;
  if (k <= 0x10000) return 2;
  return 4;
}

NbtfSizes computeSizes(const CompressedBtf& btf, std::uint64_t fileBytes) {
  // Each part's bytes as the section the writer picks for it stores them (0 when not written).
  auto partBytes = [&](format::Part part) -> std::uint64_t {
    const format::SectionKind* kind = format::writtenSection(btf, part);
    return kind && kind->tableBytes ? kind->tableBytes(btf) : 0;
  };
  NbtfSizes s;
  for (const auto& layer : btf.decoder.layers) s.decoderParameters += layer.parameterCount();
  s.decoderBytesPerValue = btf.storage.decoderInt8 ? 1 : btf.storage.decoderHalf ? 2 : 4;
  s.latentBytesPerValue = btf.storage.latentsHalf ? 2 : 4;
  s.decoder = partBytes(format::Part::Decoder);
  s.latentRows = static_cast<std::uint64_t>(std::max(btf.latentRows, 0));
  s.latentDim = btf.latentDim;
  s.latents = partBytes(format::Part::Latents);
  s.texels = static_cast<std::uint64_t>(std::max(btf.numTexels(), 0));
  s.images = static_cast<std::uint64_t>(btf.numImages());
  if (btf.isPca()) {
    s.pca = true;
    s.pcaComponents = btf.latentDim;
    s.pcaMean = partBytes(format::Part::PcaMean);
    s.pcaBasis = partBytes(format::Part::PcaBasis);
    s.pcaCoefficients = partBytes(format::Part::PcaCoefficients);
  }
  if (btf.method == CodecMethod::ClusteredNeural) {
    s.idWidth = idWidthForClusters(btf.latentRows);
    s.ids = partBytes(format::Part::Ids);
    s.idsPaper = s.texels * 4;
    s.idsZstd = btf.storage.idsZstd && btf.ids.size() == s.texels;
  }
  if (!btf.modulation.empty()) {
    s.modulationTerms = btf.modulation.terms;
    s.modulationChannels = btf.modulation.channels;
    s.modulationBits = btf.modulation.bits;
    s.modulationDecorrelated = btf.modulation.decorrelated;
    s.modulation = partBytes(format::Part::Modulation);
  }
  if (!btf.planes.empty()) {
    s.planeResolution = btf.planes.resolution;
    s.planeFeatures = btf.planes.features;
    s.planeBytesPerValue = storagePlanesHalf(btf) ? 2 : 4;
    s.planes = partBytes(format::Part::Planes);
  }
  if (!btf.clusterPlanes.empty()) {
    s.clusterPlaneResolution = btf.clusterPlanes.resolution;
    s.clusterPlaneFeatures = btf.clusterPlanes.features;
    s.clusterPlaneBytesPerValue = format::clusterPlaneBytesPerValue(btf);
    s.clusterPlanes = partBytes(format::Part::ClusterPlanes);
  }
  s.total = format::tableBytesWritten(btf);
  // The same model stored the paper's way: float32 decoder, planes and latents, 4-byte ids.
  s.totalPaper = format::paperBytesWritten(btf);
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
  if (s.clusterPlanes)
    out += row("cl. planes", s.clusterPlanes,
               withCommas(s.latentRows) + " rows x 3 planes x " + std::to_string(s.clusterPlaneResolution) + " x " +
                   std::to_string(s.clusterPlaneResolution) + " points x " + std::to_string(s.clusterPlaneFeatures) +
                   " features" +
                   (s.clusterPlaneBytesPerValue == 1 ? std::string(": 8-bit codes, a float32 range per row and feature")
                                                     : precision(s.clusterPlaneBytesPerValue)));
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
                  s.modulationDecorrelated ? " (per RGB channel, decorrelated)"
                  : s.modulationChannels > 1 ? " (per RGB channel)" : "",
                  s.modulationBits,
                  s.texels ? 8.0 * s.modulation / s.texels : 0.0);
    out += row("per-texel", s.modulation, note);
  }
  out += row("total", s.total,
             std::string(s.planes ? "decoder + planes" : "decoder") + (s.clusterPlanes ? " + cluster planes" : "") +
                 " + latents + id list" +
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

}  // namespace nbtf
