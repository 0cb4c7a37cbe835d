// `nbtf info --json` of a .nbtf file: the description front ends share (the command line
// prints it, the Python module's Material.info parses it).
#pragma once
#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <string>

#include "codec/nbtf_file.h"

namespace nbtf {

// The bytes of a file's parts, the one description `nbtf info --json` ("bytes"), the Python
// module's Material.sizes and `nbtf compress --stats-json` give: a PCA file's pca_mean,
// pca_basis, pca_coefficients and pca_components; a neural file's decoder, latents, ids,
// modulation, planes and cluster_planes (0 where absent), decoder_parameters, latent_rows,
// latent_dim and the paper's 4-byte-id ids_paper, total_paper and ratio_paper; both total,
// raw_float32, file (0 = not known) and ratio (raw float32 / total).
nlohmann::json nbtfPartBytes(const NbtfSizes& sizes);

// The JSON object (kind, file, format_version, method, geometry, clusters, decoder shape,
// bytes (nbtfPartBytes), ratio, metadata), indented by 2.
// `fileBytes` is the size on disk (0 = unknown).
std::string nbtfInfoJson(const CompressedBtf& btf, const std::string& path, std::uint64_t fileBytes);

}  // namespace nbtf
