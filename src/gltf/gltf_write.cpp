#include "gltf/gltf_write.h"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <vector>

#include "io/image_io.h"
#include "util/error.h"
#include "util/output_folder.h"

namespace nbtf::gltf {

const char* const kGltfFileName = "material.gltf";
const char* const kFitReportName = "fit_report.json";
const char* const kGltfGenerator = "nbtf";

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kFloat = 5126, kUnsignedInt = 5125, kArrayBuffer = 34962, kElementArrayBuffer = 34963;
constexpr int kNearest = 9728, kLinearMipmapLinear = 9987, kRepeat = 10497;
const char* const kMeshesName = "meshes.bin";

struct Mesh {
  std::string name;
  std::vector<float> positions, normals, uvs;
  std::vector<std::uint32_t> indices;
};

Mesh planeMesh() {
  Mesh m;
  m.name = "plane";
  m.positions = {-1, 0, 1, 1, 0, 1, 1, 0, -1, -1, 0, -1};
  m.normals = {0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0};
  m.uvs = {0, 0, 1, 0, 1, 1, 0, 1};
  m.indices = {0, 1, 2, 0, 2, 3};  // counter-clockwise seen from +y
  return m;
}

Mesh sphereMesh(int rings = 32, int segments = 64) {
  Mesh m;
  m.name = "sphere";
  for (int r = 0; r <= rings; ++r) {
    const double theta = kPi * r / rings;
    for (int s = 0; s <= segments; ++s) {
      const double phi = 2 * kPi * s / segments;
      const double n[3] = {std::sin(theta) * std::cos(phi), std::cos(theta), -std::sin(theta) * std::sin(phi)};
      for (int c = 0; c < 3; ++c) m.positions.push_back(static_cast<float>(n[c])), m.normals.push_back(static_cast<float>(n[c]));
      m.uvs.push_back(static_cast<float>(phi / (2 * kPi)));
      m.uvs.push_back(static_cast<float>(theta / (2 * kPi)));
    }
  }
  const int row = segments + 1;
  for (int r = 0; r < rings; ++r)
    for (int s = 0; s < segments; ++s) {
      const std::uint32_t a = r * row + s, b = a + row;
      m.indices.insert(m.indices.end(), {a, b, a + 1, a + 1, b, b + 1});
    }
  return m;
}

// Appends `data` to the buffer (4-byte aligned) as a buffer view and an accessor; returns the
// accessor's index.
int addAccessor(json& j, std::vector<std::uint8_t>& buffer, const void* data, std::size_t bytes, int componentType,
                std::size_t count, const char* type, int target, const std::vector<float>* minMaxOf = nullptr) {
  while (buffer.size() % 4) buffer.push_back(0);
  const std::size_t offset = buffer.size();
  buffer.resize(offset + bytes);
  std::memcpy(buffer.data() + offset, data, bytes);
  j["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes}, {"target", target}});
  json accessor = {{"bufferView", j["bufferViews"].size() - 1}, {"componentType", componentType},
                   {"count", count}, {"type", type}};
  if (minMaxOf) {  // POSITION needs its bounds
    std::vector<float> lo(3, INFINITY), hi(3, -INFINITY);
    for (std::size_t i = 0; i < minMaxOf->size(); ++i)
      lo[i % 3] = std::min(lo[i % 3], (*minMaxOf)[i]), hi[i % 3] = std::max(hi[i % 3], (*minMaxOf)[i]);
    accessor["min"] = lo, accessor["max"] = hi;
  }
  j["accessors"].push_back(accessor);
  return static_cast<int>(j["accessors"].size() - 1);
}

void addMesh(json& j, std::vector<std::uint8_t>& buffer, const Mesh& m) {
  const std::size_t vertices = m.positions.size() / 3;
  const int pos = addAccessor(j, buffer, m.positions.data(), m.positions.size() * 4, kFloat, vertices, "VEC3",
                              kArrayBuffer, &m.positions);
  const int nor = addAccessor(j, buffer, m.normals.data(), m.normals.size() * 4, kFloat, vertices, "VEC3", kArrayBuffer);
  const int uv = addAccessor(j, buffer, m.uvs.data(), m.uvs.size() * 4, kFloat, vertices, "VEC2", kArrayBuffer);
  const int idx = addAccessor(j, buffer, m.indices.data(), m.indices.size() * 4, kUnsignedInt, m.indices.size(),
                              "SCALAR", kElementArrayBuffer);
  j["meshes"].push_back({{"name", m.name},
                         {"primitives",
                          {{{"attributes", {{"POSITION", pos}, {"NORMAL", nor}, {"TEXCOORD_0", uv}}},
                            {"indices", idx},
                            {"material", 0}}}}});
}

json gltfDocument(double exposure, const std::string& materialName, std::size_t bufferBytes, const TextureSet& t) {
  const bool sheen = !t.sheen.empty();
  json j;
  j["asset"] = {{"version", "2.0"}, {"generator", std::string(kGltfGenerator) + " export-gltf"}};
  j["scene"] = 0;
  j["scenes"] = {{{"nodes", {0, 1}}}};
  j["nodes"] = {{{"name", "plane"}, {"mesh", 0}}, {{"name", "sphere"}, {"mesh", 1}, {"translation", {3, 1, 0}}}};
  j["samplers"] = {{{"magFilter", kNearest}, {"minFilter", kLinearMipmapLinear}, {"wrapS", kRepeat}, {"wrapT", kRepeat}}};
  j["images"] = {{{"uri", "base_color.png"}}, {{"uri", "metallic_roughness.png"}}, {{"uri", "normal.png"}}};
  j["textures"] = {{{"sampler", 0}, {"source", 0}}, {{"sampler", 0}, {"source", 1}}, {{"sampler", 0}, {"source", 2}}};
  j["materials"] = {{{"name", materialName},
                     {"pbrMetallicRoughness",
                      {{"baseColorTexture", {{"index", 0}}},
                       {"metallicRoughnessTexture", {{"index", 1}}},
                       {"metallicFactor", 1.0},
                       {"roughnessFactor", 1.0}}},
                     {"normalTexture", {{"index", 2}}},
                     {"extras",
                      {{"nbtf",
                        {{"exposure", exposure},
                         {"note", "light with a sun (directional light) of this strength to reproduce the BTF's values"}}}}}}};
  j["buffers"] = {{{"uri", kMeshesName}, {"byteLength", bufferBytes}}};
  if (sheen) {  // one RGBA image: the colour in RGB, the roughness in alpha (the extension's channels)
    j["images"].push_back({{"uri", "sheen.png"}});
    j["textures"].push_back({{"sampler", 0}, {"source", 3}});
    j["materials"][0]["extensions"]["KHR_materials_sheen"] = {{"sheenColorFactor", {1.0, 1.0, 1.0}},
                                                              {"sheenColorTexture", {{"index", 3}}},
                                                              {"sheenRoughnessFactor", 1.0},
                                                              {"sheenRoughnessTexture", {{"index", 3}}}};
    j["extensionsUsed"].push_back("KHR_materials_sheen");
  }
  if (!t.specular.empty()) {  // a grey specular colour: the dielectric's F0 = 0.04 x factor x texture
    const std::size_t index = j["images"].size();
    j["images"].push_back({{"uri", "specular.png"}});
    j["textures"].push_back({{"sampler", 0}, {"source", index}});
    const double f = t.specularColorFactor;
    j["materials"][0]["extensions"]["KHR_materials_specular"] = {{"specularFactor", 1.0},
                                                                 {"specularColorFactor", {f, f, f}},
                                                                 {"specularColorTexture", {{"index", index}}}};
    j["extensionsUsed"].push_back("KHR_materials_specular");
  }
  return j;
}

std::size_t writePng(const fs::path& path, int width, int height, const std::vector<std::uint8_t>& rgb) {
  Image8 image;
  image.width = width, image.height = height, image.rgb = rgb;
  writeImage8(path.string(), ImageFormat::Png, image);
  return static_cast<std::size_t>(fs::file_size(path));
}

const OutputFolderKind& gltfFolderKind() {
  static const OutputFolderKind kind{"a glTF export", kGltfFileName, [](const fs::path& folder) {
                                       std::ifstream in(folder / kGltfFileName);
                                       const json j = json::parse(in, nullptr, false);
                                       if (!j.is_object() || !j.contains("asset") || !j["asset"].is_object()) return false;
                                       const std::string generator = j["asset"].value("generator", "");
                                       return generator.rfind(kGltfGenerator, 0) == 0;
                                     }};
  return kind;
}

}  // namespace

void checkGltfOutput(const std::string& dir) { checkReplaceableFolder(dir, gltfFolderKind()); }

TextureBytes writeGltfExport(const std::string& dir, const TextureSet& t, double exposure,
                             const std::string& materialName, const std::string& reportJson) {
  TextureBytes bytes;
  writeFolderAtomic(dir, gltfFolderKind(), [&](const fs::path& tmp) {
    bytes.baseColor = writePng(tmp / "base_color.png", t.width, t.height, t.baseColor);
    bytes.metallicRoughness = writePng(tmp / "metallic_roughness.png", t.width, t.height, t.metallicRoughness);
    bytes.normal = writePng(tmp / "normal.png", t.width, t.height, t.normal);
    if (!t.sheen.empty()) {
      ImageRgba8 sheen;
      sheen.width = t.width, sheen.height = t.height, sheen.rgba = t.sheen;
      writeImageRgba8((tmp / "sheen.png").string(), sheen);
      bytes.sheen = static_cast<std::size_t>(fs::file_size(tmp / "sheen.png"));
    }
    if (!t.specular.empty()) bytes.specular = writePng(tmp / "specular.png", t.width, t.height, t.specular);
    std::vector<std::uint8_t> buffer;
    json doc;
    addMesh(doc, buffer, planeMesh());
    addMesh(doc, buffer, sphereMesh());
    while (buffer.size() % 4) buffer.push_back(0);
    json full = gltfDocument(exposure, materialName, buffer.size(), t);
    for (const char* key : {"bufferViews", "accessors", "meshes"}) full[key] = doc[key];
    writeWholeFile(tmp / kMeshesName, buffer.data(), buffer.size());
    const std::string text = full.dump(2) + "\n";
    writeWholeFile(tmp / kGltfFileName, text.data(), text.size());
    json report = json::parse(reportJson);
    report["texture_bytes"] = {{"base_color", bytes.baseColor},
                               {"metallic_roughness", bytes.metallicRoughness},
                               {"normal", bytes.normal},
                               {"sheen", bytes.sheen},
                               {"specular", bytes.specular},
                               {"total", bytes.total()}};
    if (report.contains("raw_bytes") && bytes.total() > 0)
      report["compression_ratio"] = report["raw_bytes"].get<double>() / double(bytes.total());
    const std::string reportText = report.dump(2) + "\n";
    writeWholeFile(tmp / kFitReportName, reportText.data(), reportText.size());
  });
  return bytes;
}

}  // namespace nbtf::gltf
