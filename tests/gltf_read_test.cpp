// Reading a glTF material back (gltf/gltf_read.h): an export comes back as its textures say;
// what the reader cannot take is refused with the file and the field.
#include "gltf/gltf_read.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "gltf/gltf_write.h"
#include "io/image_io.h"
#include "test_util.h"

namespace nbtf::gltf {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

GltfMaterial material() {
  GltfMaterial m;
  m.width = 4, m.height = 2, m.exposure = 2.5;
  m.texels.resize(8);
  for (int i = 0; i < 8; ++i) {
    m.texels[i].brdf.baseColor = {0.1 * i, 0.3, 0.9 - 0.1 * i};
    m.texels[i].brdf.roughness = 0.3 + 0.05 * i;
    m.texels[i].brdf.metallic = i == 3 ? 1 : 0;
    const double s = std::sqrt(1 + 0.04 * i * i);
    m.texels[i].normal = {0.2 * i / s, 0, 1 / s};
  }
  return m;
}

fs::path exported(const std::string& name) {
  const fs::path dir = test::tempFilePath(name);
  fs::remove_all(dir);
  writeGltfExport(dir.string(), quantize(material()), 2.5, "m", "{}");
  return dir;
}

void editDocument(const fs::path& file, const std::function<void(json&)>& edit) {
  std::ifstream in(file);
  json j = json::parse(in);
  in.close();
  edit(j);
  std::ofstream(file) << j.dump();
}

TEST(GltfRead, AnExportComesBackAsItsTexturesSay) {
  const fs::path dir = exported("gltf_read_roundtrip");
  const GltfMaterial back = readGltfMaterial((dir / kGltfFileName).string());
  const GltfMaterial want = dequantize(quantize(material()), 2.5, "want");
  ASSERT_EQ(back.width, 4);
  ASSERT_EQ(back.height, 2);
  EXPECT_EQ(back.exposure, 2.5);
  for (int i = 0; i < 8; ++i) {
    EXPECT_EQ(back.texels[i].brdf.baseColor, want.texels[i].brdf.baseColor);
    EXPECT_EQ(back.texels[i].brdf.roughness, want.texels[i].brdf.roughness);
    EXPECT_EQ(back.texels[i].brdf.metallic, want.texels[i].brdf.metallic);
    EXPECT_EQ(back.texels[i].normal, want.texels[i].normal);
  }
  EXPECT_TRUE(isGltfPath("a/material.gltf"));
  EXPECT_FALSE(isGltfPath("a/material.nbtf"));
}

TEST(GltfRead, SheenComesBackFromTheExtension) {
  GltfMaterial m = material();
  m.sheen = true;
  for (int i = 0; i < 8; ++i) m.texels[i].brdf.sheenColor = {0.05 * i, 0.2, 0.1}, m.texels[i].brdf.sheenRoughness = 0.1 * i;
  const fs::path dir = test::tempFilePath("gltf_read_sheen");
  fs::remove_all(dir);
  writeGltfExport(dir.string(), quantize(m), 2.5, "m", "{}");
  std::ifstream in(dir / kGltfFileName);
  const json j = json::parse(in);
  EXPECT_EQ(j["extensionsUsed"], json::array({"KHR_materials_sheen"}));
  EXPECT_EQ(j["materials"][0]["extensions"]["KHR_materials_sheen"]["sheenRoughnessTexture"]["index"], 3);
  const GltfMaterial back = readGltfMaterial((dir / kGltfFileName).string());
  const GltfMaterial want = dequantize(quantize(m), 2.5, "want");
  ASSERT_TRUE(back.sheen);
  for (int i = 0; i < 8; ++i) {
    EXPECT_EQ(back.texels[i].brdf.sheenColor, want.texels[i].brdf.sheenColor);
    EXPECT_EQ(back.texels[i].brdf.sheenRoughness, want.texels[i].brdf.sheenRoughness);
  }
  editDocument(dir / kGltfFileName, [](json& doc) {
    doc["materials"][0]["extensions"]["KHR_materials_sheen"]["sheenRoughnessFactor"] = 0.5;
  });
  EXPECT_NEAR(readGltfMaterial((dir / kGltfFileName).string()).texels[6].brdf.sheenRoughness,
              0.5 * want.texels[6].brdf.sheenRoughness, 1e-12);
}

TEST(GltfRead, SpecularComesBackAndWhatItCannotExpressIsRefused) {
  GltfMaterial m = material();
  m.specular = true;
  for (int i = 0; i < 8; ++i) m.texels[i].brdf.specularF0 = 0.01 * (i + 1);
  const fs::path dir = test::tempFilePath("gltf_read_specular");
  fs::remove_all(dir);
  writeGltfExport(dir.string(), quantize(m), 2.5, "m", "{}");
  const std::string file = (dir / kGltfFileName).string();
  const GltfMaterial back = readGltfMaterial(file), want = dequantize(quantize(m), 2.5, "want");
  ASSERT_TRUE(back.specular);
  for (int i = 0; i < 8; ++i) EXPECT_NEAR(back.texels[i].brdf.specularF0, want.texels[i].brdf.specularF0, 1e-12);
  editDocument(file, [](json& j) { j["materials"][0]["extensions"]["KHR_materials_specular"]["specularFactor"] = 0.5; });
  test::expectErrorContaining([&] { readGltfMaterial(file); }, {file, "KHR_materials_specular", "specularFactor 1"});
  editDocument(file, [](json& j) {
    auto& e = j["materials"][0]["extensions"]["KHR_materials_specular"];
    e["specularFactor"] = 1.0;
    e["specularColorFactor"] = {1.0, 0.5, 1.0};
  });
  test::expectErrorContaining([&] { readGltfMaterial(file); }, {"specularColorFactor", "grey"});
}

TEST(GltfRead, FactorsMultiplyTheTexturesAndAMaterialWithoutTexturesIsOneTexel) {
  const fs::path dir = exported("gltf_read_factors");
  const fs::path file = dir / kGltfFileName;
  editDocument(file, [](json& j) {
    j["materials"][0]["pbrMetallicRoughness"]["roughnessFactor"] = 0.5;
    j["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"] = {0.5, 1, 1, 1};
  });
  const GltfMaterial m = readGltfMaterial(file.string());
  const GltfMaterial want = dequantize(quantize(material()), 2.5, "want");
  EXPECT_NEAR(m.texels[2].brdf.roughness, 0.5 * want.texels[2].brdf.roughness, 1e-12);
  EXPECT_NEAR(m.texels[2].brdf.baseColor[0], 0.5 * want.texels[2].brdf.baseColor[0], 1e-12);

  editDocument(file, [](json& j) {
    j["materials"][0] = {{"pbrMetallicRoughness", {{"baseColorFactor", {0.2, 0.4, 0.6, 1}}, {"metallicFactor", 0.0}}}};
  });
  const GltfMaterial plain = readGltfMaterial(file.string());
  EXPECT_EQ(plain.width, 1);
  EXPECT_EQ(plain.exposure, 1);  // no extras: a sun of strength 1
  EXPECT_NEAR(plain.texels[0].brdf.baseColor[1], 0.4, 1e-12);
  EXPECT_EQ(plain.texels[0].brdf.metallic, 0);
  EXPECT_EQ(plain.texels[0].brdf.roughness, 1);
  EXPECT_NEAR(plain.texels[0].normal[2], 1, 1e-4);
}

TEST(GltfRead, WhatCannotBeReadIsRefusedWithTheFileAndTheField) {
  const fs::path dir = exported("gltf_read_refused");
  const std::string file = (dir / kGltfFileName).string();
  editDocument(file, [](json& j) { j["images"][0]["uri"] = "data:image/png;base64,AAAA"; });
  test::expectErrorContaining([&] { readGltfMaterial(file); }, {file, "images[0].uri", "data URIs"});
  editDocument(file, [](json& j) { j["images"][0]["uri"] = "missing.png"; });
  test::expectErrorContaining([&] { readGltfMaterial(file); }, {"missing.png"});
  editDocument(file, [](json& j) { j["images"][0]["uri"] = "base_color.png"; j["asset"]["version"] = "1.0"; });
  test::expectErrorContaining([&] { readGltfMaterial(file); }, {file, "asset.version"});
  editDocument(file, [](json& j) {
    j["asset"]["version"] = "2.0";
    j["materials"][0]["normalTexture"]["texCoord"] = 1;
  });
  test::expectErrorContaining([&] { readGltfMaterial(file); }, {"materials[0].normalTexture.texCoord", "TEXCOORD_0"});
  editDocument(file, [](json& j) { j["materials"][0]["normalTexture"].erase("texCoord"); });
  Image8 small;
  small.width = small.height = 1;
  small.rgb = {1, 2, 3};
  writeImage8((dir / "normal.png").string(), ImageFormat::Png, small);
  test::expectErrorContaining([&] { readGltfMaterial(file); }, {file, "differ in size"});
  std::ofstream(file) << "{ not json";
  test::expectErrorContaining([&] { readGltfMaterial(file); }, {file, "not valid JSON"});
}

}  // namespace
}  // namespace nbtf::gltf
