// Writing a glTF 2.0 export: material.gltf (the material on a plane and a sphere,
// so that it opens as it is), meshes.bin, the textures as PNG (base colour in sRGB,
// metallic-roughness and the tangent-space normal map in linear 8-bit; with sheen, sheen.png:
// KHR_materials_sheen's colour in sRGB and its roughness in alpha; with specular, specular.png:
// KHR_materials_specular's grey colour texture) and fit_report.json.
// The folder is written as a whole or not at all (util/output_folder.h); only a new or empty
// folder or an earlier export is replaced.
//
// The meshes: the plane is `nbtf render --scene plane`'s 2 x 2 square (y = 0, u along +x,
// v along -z: texture coordinate (u, v) = (x + 1, 1 - z) / 2), the sphere (radius 1, centre
// (3, 1, 0)) has u = phi / 2 pi, v = theta / 2 pi as the renderer's sphere. Tangents are not
// written: renderers compute MikkTSpace ones, as the specification asks. Textures sample with
// NEAREST magnification, so a texel is a texel as in nbtf's own renderer.
#pragma once
#include <string>

#include "gltf/gltf_material.h"

namespace nbtf::gltf {

extern const char* const kGltfFileName;      // "material.gltf"
extern const char* const kFitReportName;     // "fit_report.json"
extern const char* const kGltfGenerator;     // the asset.generator nbtf writes ("nbtf <version>" starts with it)

struct TextureBytes {
  std::size_t baseColor = 0, metallicRoughness = 0, normal = 0, sheen = 0, specular = 0;
  std::size_t total() const { return baseColor + metallicRoughness + normal + sheen + specular; }
};

// Writes the folder; `reportJson` (an object) is completed with the textures' bytes (and,
// when it holds "raw_bytes", the compression ratio raw / textures) and written as
// fit_report.json. Returns the PNG bytes written.
TextureBytes writeGltfExport(const std::string& dir, const TextureSet& textures, double exposure,
                             const std::string& materialName, const std::string& reportJson);

// Throws nbtf::Error naming `dir` when it exists and is not empty or an earlier glTF export.
void checkGltfOutput(const std::string& dir);

}  // namespace nbtf::gltf
