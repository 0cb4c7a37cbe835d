// Human-readable description of a .nbtf file: what `nbtf info <file.nbtf>` prints.
#pragma once
#include <cstdint>
#include <string>

#include "codec/nbtf_file.h"

namespace nbtf {

// Method, geometry, sampling, decoder shape, hold-out set, training statistics from the
// metadata, and the Table-1 size table. `fileBytes` is the size on disk (0 = unknown).
std::string describeNbtf(const CompressedBtf& btf, const std::string& path, std::uint64_t fileBytes);

}  // namespace nbtf
