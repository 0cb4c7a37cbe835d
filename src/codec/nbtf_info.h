// `nbtf info --json` of a .nbtf file: the description front ends share (the command line
// prints it, the Python module's Material.info parses it).
#pragma once
#include <cstdint>
#include <string>

#include "codec/nbtf_file.h"

namespace nbtf {

// The JSON object (kind, file, format_version, method, geometry, clusters, decoder shape,
// bytes {decoder, latents, ids, total, raw_float32, file}, ratio, metadata), indented by 2.
// `fileBytes` is the size on disk (0 = unknown).
std::string nbtfInfoJson(const CompressedBtf& btf, const std::string& path, std::uint64_t fileBytes);

}  // namespace nbtf
