// The checks of each stored part on its own (part_checks.cpp), one per row of the part table
// (format::partRows). Each throws nbtf::Error naming `name` (the file) and what is wrong.
#pragma once
#include <string>

#include "codec/nbtf_file.h"

namespace nbtf::format {

void checkDecoderPart(const CompressedBtf& btf, const std::string& name);  // also the latent dimension
void checkDirectionPlanesPart(const CompressedBtf& btf, const std::string& name);
void checkClusterPlanesPart(const CompressedBtf& btf, const std::string& name);
void checkLatentsPart(const CompressedBtf& btf, const std::string& name);
void checkIdsPart(const CompressedBtf& btf, const std::string& name);
void checkModulationPart(const CompressedBtf& btf, const std::string& name);  // none stored: nothing to check
void checkPcaMeanPart(const CompressedBtf& btf, const std::string& name);
void checkPcaBasisPart(const CompressedBtf& btf, const std::string& name);
void checkPcaCoefficientsPart(const CompressedBtf& btf, const std::string& name);

}  // namespace nbtf::format
