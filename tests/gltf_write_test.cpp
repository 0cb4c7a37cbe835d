// The glTF export folder (gltf/gltf_write.h): a document every glTF reader takes (the required
// fields, buffers and images that exist, accessors inside their buffer views, indices and
// texture values in range), replaced only when it is nbtf's own.
#include "gltf/gltf_write.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "io/image_io.h"
#include "test_util.h"

namespace nbtf::gltf {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

TextureSet smallTextures() {
  GltfMaterial m;
  m.width = 5, m.height = 3;
  m.texels.resize(15);
  for (int i = 0; i < 15; ++i) {
    m.texels[i].brdf.baseColor = {i / 15.0, 0.5, 1 - i / 15.0};
    m.texels[i].brdf.roughness = 0.2 + i / 30.0;
    m.texels[i].brdf.metallic = i % 2;
  }
  return quantize(m);
}

fs::path freshDir(const std::string& name) {
  const fs::path dir = test::tempFilePath(name);
  fs::remove_all(dir);
  return dir;
}

std::vector<std::uint8_t> fileBytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

TEST(GltfWrite, TheDocumentHasEveryRequiredFieldAndEverythingItNamesExists) {
  const fs::path dir = freshDir("gltf_write_valid");
  const TextureBytes bytes = writeGltfExport(dir.string(), smallTextures(), 3.5, "test", R"({"raw_bytes": 1000})");
  std::ifstream in(dir / kGltfFileName);
  const json j = json::parse(in);
  EXPECT_EQ(j["asset"]["version"], "2.0");
  EXPECT_EQ(j["asset"]["generator"].get<std::string>().rfind(kGltfGenerator, 0), 0u);
  EXPECT_EQ(j["materials"][0]["extras"]["nbtf"]["exposure"], 3.5);
  // Buffer: the file exists with the declared length; every view lies inside it; every
  // accessor inside its view.
  ASSERT_EQ(j["buffers"].size(), 1u);
  const std::vector<std::uint8_t> buffer = fileBytes(dir / j["buffers"][0]["uri"].get<std::string>());
  EXPECT_EQ(buffer.size(), j["buffers"][0]["byteLength"].get<std::size_t>());
  for (const json& v : j["bufferViews"])
    EXPECT_LE(v["byteOffset"].get<std::size_t>() + v["byteLength"].get<std::size_t>(), buffer.size());
  const std::map<std::string, int> components = {{"SCALAR", 1}, {"VEC2", 2}, {"VEC3", 3}};
  for (const json& a : j["accessors"]) {
    const json& view = j["bufferViews"][a["bufferView"].get<std::size_t>()];
    EXPECT_LE(a["count"].get<std::size_t>() * components.at(a["type"]) * 4, view["byteLength"].get<std::size_t>());
  }
  // Two meshes (plane, sphere) on two nodes of the scene; POSITION has its bounds; indices in range.
  ASSERT_EQ(j["meshes"].size(), 2u);
  EXPECT_EQ(j["nodes"][0]["name"], "plane");
  EXPECT_EQ(j["scenes"][0]["nodes"], json::array({0, 1}));
  for (const json& mesh : j["meshes"]) {
    const json& prim = mesh["primitives"][0];
    const json& pos = j["accessors"][prim["attributes"]["POSITION"].get<std::size_t>()];
    EXPECT_TRUE(pos.contains("min") && pos.contains("max"));
    const json& idx = j["accessors"][prim["indices"].get<std::size_t>()];
    const json& view = j["bufferViews"][idx["bufferView"].get<std::size_t>()];
    const auto* indices = reinterpret_cast<const std::uint32_t*>(buffer.data() + view["byteOffset"].get<std::size_t>());
    for (std::size_t i = 0; i < idx["count"].get<std::size_t>(); ++i) EXPECT_LT(indices[i], pos["count"].get<std::uint32_t>());
    EXPECT_EQ(prim["material"], 0);
  }
  // Images exist, have the material's size, and hold what was quantized.
  const TextureSet t = smallTextures();
  ASSERT_EQ(j["images"].size(), 3u);
  const std::vector<std::uint8_t>* want[] = {&t.baseColor, &t.metallicRoughness, &t.normal};
  for (int i = 0; i < 3; ++i) {
    const Image8 img = readImage8((dir / j["images"][i]["uri"].get<std::string>()).string());
    EXPECT_EQ(img.width, 5);
    EXPECT_EQ(img.height, 3);
    EXPECT_EQ(img.rgb, *want[i]) << j["images"][i]["uri"];
  }
  for (const json& tex : j["textures"]) EXPECT_LT(tex["source"].get<std::size_t>(), j["images"].size());
  // The report gets the textures' bytes and the ratio.
  std::ifstream rin(dir / kFitReportName);
  const json report = json::parse(rin);
  EXPECT_EQ(report["texture_bytes"]["total"].get<std::size_t>(), bytes.total());
  EXPECT_EQ(bytes.total(), fs::file_size(dir / "base_color.png") + fs::file_size(dir / "metallic_roughness.png") +
                               fs::file_size(dir / "normal.png"));
  EXPECT_NEAR(report["compression_ratio"].get<double>(), 1000.0 / bytes.total(), 1e-9);
}

TEST(GltfWrite, AnEarlierExportIsReplacedAndAnythingElseRefusedWithNothingWritten) {
  const fs::path dir = freshDir("gltf_write_replace");
  writeGltfExport(dir.string(), smallTextures(), 1, "a", "{}");
  writeGltfExport(dir.string(), smallTextures(), 2, "b", "{}");  // ours: replaced
  std::ifstream in(dir / kGltfFileName);
  EXPECT_EQ(json::parse(in)["materials"][0]["name"], "b");

  const fs::path foreign = freshDir("gltf_write_foreign");
  fs::create_directories(foreign);
  std::ofstream(foreign / "photo.jpg") << "precious";
  test::expectErrorContaining([&] { writeGltfExport(foreign.string(), smallTextures(), 1, "a", "{}"); },
                              {foreign.string(), "is not a glTF export"});
  test::expectErrorContaining([&] { checkGltfOutput(foreign.string()); }, {"is not a glTF export"});
  // Someone else's material.gltf is not ours either.
  std::ofstream(foreign / kGltfFileName) << R"({"asset": {"version": "2.0", "generator": "Blender"}})";
  test::expectErrorContaining([&] { checkGltfOutput(foreign.string()); }, {"is not a glTF export"});
  std::size_t entries = 0;
  for (const auto& e : fs::directory_iterator(foreign)) (void)e, ++entries;
  EXPECT_EQ(entries, 2u);
  for (const auto& e : fs::directory_iterator(foreign.parent_path()))  // no temporary folder left beside it
    EXPECT_EQ(e.path().filename().string().find(".nbtf_test_gltf_write_foreign.tmp-"), std::string::npos);
}

}  // namespace
}  // namespace nbtf::gltf
