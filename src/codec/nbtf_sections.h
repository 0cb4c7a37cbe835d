// The sections of a .nbtf file as one table: each entry is one tag with its label, the
// format version that introduced it, whether a reader that does not know it must refuse the
// file, which part of the material it holds, and its writer, reader and Table-1 byte count.
// The writer (codec/nbtf_file.cpp) walks the table in order, writes the sections whose
// `written` says so, and takes the file's version as the highest `minor` among them; the reader
// dispatches on the tag and checks the parts against the method: which parts a method needs is
// its model kind's (codec/methods/method.h). A new encoding of a part is one new entry here; a
// new part is its entry, its Part, and the kinds that need it.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "codec/nbtf_file.h"
#include "util/byte_io.h"

namespace nbtf::format {

// What a section holds. Sections of one part are alternative encodings of it (float32 or
// half, raw or zstd): a file holds at most one of them.
enum class Part {
  Info,
  Directions,
  Decoder,
  Latents,
  PcaMean,
  PcaBasis,
  PcaCoefficients,
  Ids,
  Modulation,
  Planes,
  ClusterPlanes,
  Holdout,
  Encoder,
  Metadata,
};

// A section as found in a file: its header fields and where its payload lies.
struct SectionRef {
  std::uint32_t tag = 0;
  std::uint32_t flags = 0;
  std::size_t offset = 0;  // of the section header
  const std::uint8_t* payload = nullptr;
  std::size_t size = 0;
  std::uint32_t crc = 0;
};

struct SectionKind {
  std::uint32_t tag;
  const char* label;  // "decoder, half precision"
  Part part;
  bool required;       // flagged so that a reader that does not know the tag refuses the file
  std::uint16_t minor;  // the format minor version that introduced the section
  // The minor version this content needs when it is higher than `minor` (INFO: the direction
  // encoding); null when `minor` is all.
  std::uint16_t (*contentMinor)(const CompressedBtf&);
  bool (*written)(const CompressedBtf&);  // does the writer store the material's part this way?
  void (*write)(const CompressedBtf&, ByteWriter&);
  // Reads the payload into `btf`; sections before it in the file are already read (INFO first).
  void (*parse)(const SectionRef&, CompressedBtf& btf, const std::string& name);
  // The bytes the paper's Table 1 counts for this part as stored (0 for provenance and framing).
  std::uint64_t (*tableBytes)(const CompressedBtf&);
  // The same part stored the paper's way (float32 values, 4-byte ids); null = as stored.
  std::uint64_t (*paperBytes)(const CompressedBtf&);
};

// Every section this build knows, in the order the writer writes them.
const std::vector<SectionKind>& sectionKinds();
const SectionKind* findSectionKind(std::uint32_t tag);  // null for a tag this build does not know
// The section the writer stores `part` in for this material; null when it is not written.
const SectionKind* writtenSection(const CompressedBtf& btf, Part part);
// The Table-1 bytes of everything the writer stores for this material, as stored and the
// paper's way: the size table's totals (computeSizes).
std::uint64_t tableBytesWritten(const CompressedBtf& btf);
std::uint64_t paperBytesWritten(const CompressedBtf& btf);

// A part of a material: how the size table shows it (formatSizeTable: its name there and in
// the total's sum, what its bytes are made of, the row a material without the part still shows:
// null, or a note returning null for no row) and its own checks (part_checks.h), which every
// kind that may store the part runs (checkStoredParts). In the table's order (partRows()).
struct PartRow {
  Part part;
  const char* name;       // "cl. planes"
  const char* totalName;  // "cluster planes"
  std::string (*note)(const CompressedBtf&);
  const char* (*absent)(const CompressedBtf&);
  void (*check)(const CompressedBtf&, const std::string& name);
};
const std::vector<PartRow>& partRows();

// Whether a method needs a part (MethodKind::need): the reader refuses a file that lacks a
// needed part or holds one its method cannot use.
enum class Need { Optional, Required, Forbidden };
// Every part, in the order the reader checks them (Part's order; Metadata is the last).
const std::vector<Part>& checkedParts();

// "section 'DECH' (decoder, half precision)"; the label is left out for an unknown tag.
std::string sectionLabel(std::uint32_t tag);
std::string tagText(std::uint32_t tag);
// The tag of a part's first (float32, raw) encoding, named in "missing ..." errors.
std::uint32_t primaryTag(Part part);

constexpr std::uint32_t tag(const char (&s)[5]) {
  return std::uint32_t(std::uint8_t(s[0])) | std::uint32_t(std::uint8_t(s[1])) << 8 |
         std::uint32_t(std::uint8_t(s[2])) << 16 | std::uint32_t(std::uint8_t(s[3])) << 24;
}

}  // namespace nbtf::format
