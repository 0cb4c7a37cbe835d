// The .nbtf framing: the header, the section walk and checksums, and the reader's checks of
// which parts a file holds. The sections themselves are the table of codec/nbtf_sections.cpp.
#include "codec/nbtf_file.h"

#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <fstream>

#include "codec/crc32.h"
#include "codec/methods/method.h"
#include "codec/nbtf_format.h"
#include "codec/nbtf_sections.h"
#include "util/atomic_file.h"
#include "util/byte_io.h"
#include "util/error.h"

namespace nbtf {

using namespace format;

namespace {

std::string hex32(std::uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%08" PRIx32, v);
  return buf;
}

void addSection(ByteWriter& file, const SectionKind& kind, const CompressedBtf& btf) {
  ByteWriter payload;
  kind.write(btf, payload);
  const auto& p = payload.bytes();
  file.u32(kind.tag);
  file.u32(kind.required ? kSectionRequired : 0);
  file.u64(p.size());
  file.u32(crc32(p.data(), p.size()));
  file.u32(0);
  file.raw(p.data(), p.size());
  file.zeros((kAlign - p.size() % kAlign) % kAlign);
}

}  // namespace

// ---- Writing

std::vector<std::uint8_t> serializeNbtf(const CompressedBtf& btf) {
  btf.validate();
  std::vector<const SectionKind*> sections;
  std::uint16_t minor = 0;  // the lowest version that describes the file: older readers open it
  for (const SectionKind& kind : sectionKinds())
    if (kind.written(btf)) {
      sections.push_back(&kind);
      minor = std::max({minor, kind.minor, kind.contentMinor ? kind.contentMinor(btf) : std::uint16_t(0)});
    }
  ByteWriter file;
  file.raw(kNbtfMagic, sizeof kNbtfMagic);
  file.u16(kNbtfFormatMajor);
  file.u16(minor);
  file.u32(0);  // header flags (none defined)
  file.u64(0);  // file size, patched below
  file.u32(0);  // body CRC, patched below
  file.u32(0);  // header CRC, patched below
  for (const SectionKind* kind : sections) addSection(file, *kind, btf);
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

// Alternative encodings of one part (float32 or half, raw or zstd): at most one per file;
// then every part the method needs, and none it cannot use.
void checkParts(const std::vector<const SectionKind*>& present, CodecMethod method, const std::string& name) {
  for (std::size_t i = 0; i < present.size(); ++i)
    for (std::size_t j = i + 1; j < present.size(); ++j)
      if (present[i]->part == present[j]->part) {
        const bool inTableOrder = present[i] < present[j];  // name them in the writer's order
        const SectionKind* a = inTableOrder ? present[i] : present[j];
        const SectionKind* b = inTableOrder ? present[j] : present[i];
        throw fileError(name, "both " + sectionLabel(a->tag) + " and " + sectionLabel(b->tag) + " present");
      }
  const MethodKind& kind = methodKind(method, name);
  for (Part part : checkedParts()) {
    auto found = std::find_if(present.begin(), present.end(), [&](const SectionKind* k) { return k->part == part; });
    const Need need = kind.need(part);
    if (need == Need::Required && found == present.end()) {
      const MethodKind* owner = soleKindRequiring(part);
      throw fileError(name, "missing " + sectionLabel(primaryTag(part)) +
                                (owner ? std::string(" (required by the ") + owner->shortName() + " method)"
                                       : std::string()));
    }
    if (need == Need::Forbidden && found != present.end())
      throw fileError(name, sectionLabel((*found)->tag) + " present, but the method is " + kind.name());
  }
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
  if (sections.empty() || sections.front().tag != primaryTag(Part::Info))
    throw fileError(name, "corrupted: the first section must be 'INFO' (material info)");
  CompressedBtf btf;
  btf.formatMajor = major;
  btf.formatMinor = minor;
  btf.metadataJson = "{}";
  std::vector<std::uint32_t> seen;
  std::vector<const SectionKind*> present;
  for (const SectionRef& s : sections) {
    if (std::find(seen.begin(), seen.end(), s.tag) != seen.end())
      throw fileError(name, sectionLabel(s.tag) + " appears twice (offset " + std::to_string(s.offset) + ")");
    seen.push_back(s.tag);
    if (options.verifyChecksums && crc32(s.payload, s.size) != s.crc)
      throw fileError(name, "corrupted: checksum mismatch in " + sectionLabel(s.tag) + " at offset " +
                                std::to_string(s.offset));
    if (const SectionKind* kind = findSectionKind(s.tag)) {
      kind->parse(s, btf, name);
      present.push_back(kind);
    } else if (s.flags & kSectionRequired) {
      throw fileError(name, "required " + sectionLabel(s.tag) + " is unknown to this nbtf (format " + version +
                                "; written by a newer nbtf?); update nbtf");
    } else {
      btf.skippedSections.push_back(tagText(s.tag));
    }
  }
  checkParts(present, btf.method, name);
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