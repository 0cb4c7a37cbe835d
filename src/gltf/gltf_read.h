// Reading a glTF material back: what `nbtf render` and `nbtf eval` use to show and measure a
// glTF export (or any glTF file with a core metallic-roughness material).
#pragma once
#include <cstdint>
#include <string>

#include "gltf/gltf_material.h"

namespace nbtf::gltf {

// The first material of a glTF file: its base colour, metallic-roughness and normal textures
// and KHR_materials_sheen's (PNG or JPEG files beside it, all of one size; a missing texture is
// its factor alone) times their factors, and its exposure from extras.nbtf.exposure (1 when absent: a sun of strength
// 1). Throws nbtf::Error naming the file and the field for what it cannot read: embedded or
// data-URI images, textures of different sizes, another texture coordinate set, a missing file.
GltfMaterial readGltfMaterial(const std::string& path);

// The bytes of the image files the first material's textures name (the glTF fit's size on the
// rate-distortion plot); each counted once.
std::uint64_t textureFileBytes(const std::string& path);

// Whether `path` names a glTF file (by its extension: .gltf).
bool isGltfPath(const std::string& path);

}  // namespace nbtf::gltf
