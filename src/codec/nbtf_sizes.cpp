// Names and sizes of a compressed material: the Table-1 parts as stored, and their text.
#include <algorithm>
#include <cstdio>

#include "codec/nbtf_format.h"
#include "codec/nbtf_sections.h"
#include "util/printable.h"

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
  for (const format::PartRow& row : format::partRows()) {
    const format::SectionKind* kind = format::writtenSection(btf, row.part);
    if (kind && kind->tableBytes)
      s.rows.push_back({row.name, row.totalName, row.note(btf), kind->tableBytes(btf)});
    else if (const char* absent = row.absent ? row.absent(btf) : nullptr)
      s.rows.push_back({row.name, row.totalName, absent, 0});
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
std::string kib(std::uint64_t bytes) {
  char buf[32];
  if (bytes >= 10u << 20) std::snprintf(buf, sizeof buf, "%.1f MiB", bytes / (1024.0 * 1024.0));
  else std::snprintf(buf, sizeof buf, "%.1f KiB", bytes / 1024.0);
  return buf;
}
std::string row(const std::string& part, std::uint64_t bytes, const std::string& note) {
  char buf[320];
  std::snprintf(buf, sizeof buf, "  %-12s %14s B %14s  %s\n", part.c_str(), groupedDigits(bytes).c_str(),
                kib(bytes).c_str(), note.c_str());
  return buf;
}
}  // namespace

// The rows are the parts' own (codec/nbtf_sections.cpp, partRows); the total is their sum.
std::string formatSizeTable(const NbtfSizes& s) {
  std::string out = s.pca ? "sizes (PCA baseline, parts as stored in float32; KiB = 1024 bytes, the paper's KB)\n"
                          : "sizes (as in the paper's Table 1, as stored; KiB = 1024 bytes, the paper's KB)\n";
  std::string sum;
  for (const NbtfSizes::PartRow& r : s.rows) {
    out += row(r.name, r.bytes, r.note);
    sum += (sum.empty() ? "" : " + ") + r.totalName;
  }
  out += row("total", s.total, sum);
  out += row("raw float32", s.rawFloat32,
             groupedDigits(s.texels) + " texels x " + groupedDigits(s.images) + " images x 3 x 4 bytes");
  char line[160];
  std::snprintf(line, sizeof line, "  %-12s 1 : %.1f (raw float32 / total)\n", "ratio", s.ratio);
  out += line;
  if (s.idWidth && s.totalPaper != s.total) {
    std::snprintf(line, sizeof line, "  %-12s total %s, 1 : %.1f (stored the paper's way: float32, 4-byte ids)\n",
                  "paper-style", kib(s.totalPaper).c_str(), s.ratioPaper);
    out += line;
  }
  if (s.fileBytes) out += row("file", s.fileBytes, "actual .nbtf size (adds directions, header, metadata, checksums)");
  return out;
}

}  // namespace nbtf
