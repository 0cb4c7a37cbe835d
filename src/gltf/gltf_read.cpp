#include "gltf/gltf_read.h"

#include <cerrno>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>

#include "io/image_io.h"
#include "util/error.h"

namespace nbtf::gltf {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

struct Reader {
  std::string path;
  json doc;

  [[noreturn]] void fail(const std::string& field, const std::string& what) const {
    throw fileError(path, field + ": " + what);
  }

  // The image a textureInfo object points to, read (RGBA: alpha 255 where the file has none);
  // nullopt when `info` is absent.
  std::optional<ImageRgba8> texture(const json& parent, const char* key, const std::string& field) const {
    if (!parent.contains(key)) return std::nullopt;
    const json& info = parent[key];
    const std::string where = field + "." + key;
    if (!info.is_object() || !info.contains("index") || !info["index"].is_number_unsigned())
      fail(where, "needs a texture index");
    if (info.value("texCoord", 0) != 0) fail(where + ".texCoord", "only TEXCOORD_0 is supported");
    const std::size_t index = info["index"].get<std::size_t>();
    if (!doc.contains("textures") || index >= doc["textures"].size()) fail(where + ".index", "no such texture");
    const json& t = doc["textures"][index];
    if (!t.contains("source") || !t["source"].is_number_unsigned())
      fail("textures[" + std::to_string(index) + "]", "has no source image (extensions such as KTX2 are not read)");
    const std::size_t source = t["source"].get<std::size_t>();
    if (!doc.contains("images") || source >= doc["images"].size())
      fail("textures[" + std::to_string(index) + "].source", "no such image");
    const json& image = doc["images"][source];
    const std::string imageField = "images[" + std::to_string(source) + "]";
    if (!image.contains("uri") || !image["uri"].is_string())
      fail(imageField, "is not an image file (images in a buffer view, as in .glb files, are not read)");
    const std::string uri = image["uri"].get<std::string>();
    if (uri.rfind("data:", 0) == 0) fail(imageField + ".uri", "data URIs are not read; keep the images as files");
    const fs::path file = fs::path(path).parent_path() / uri;
    return readImageRgba8(file.string());
  }
};

std::vector<std::uint8_t> rgbOf(const std::optional<ImageRgba8>& image, std::size_t texels, std::uint8_t fill) {
  std::vector<std::uint8_t> rgb(3 * texels, fill);
  if (image)
    for (std::size_t i = 0; i < texels; ++i)
      for (int c = 0; c < 3; ++c) rgb[3 * i + c] = image->rgba[4 * i + c];
  return rgb;
}

double number(const json& j, const char* key, double fallback) {
  return j.contains(key) && j[key].is_number() ? j[key].get<double>() : fallback;
}

}  // namespace

std::uint64_t textureFileBytes(const std::string& path) {
  std::ifstream in(path);
  const json doc = json::parse(in, nullptr, false);
  if (!doc.is_object() || !doc.contains("images")) return 0;
  std::uint64_t total = 0;
  for (const json& image : doc["images"]) {
    if (!image.contains("uri") || !image["uri"].is_string()) continue;
    std::error_code ec;
    const auto size = fs::file_size(fs::path(path).parent_path() / image["uri"].get<std::string>(), ec);
    if (!ec) total += size;
  }
  return total;
}

bool isGltfPath(const std::string& path) {
  const std::string ext = fs::path(path).extension().string();
  return ext == ".gltf" || ext == ".GLTF";
}

GltfMaterial readGltfMaterial(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw fileAccessError(path, "cannot be read", errno);
  Reader r{path, json::parse(in, nullptr, false)};
  if (r.doc.is_discarded() || !r.doc.is_object()) throw fileError(path, "is not a glTF file (not valid JSON)");
  if (!r.doc.contains("asset") || !r.doc["asset"].is_object() || r.doc["asset"].value("version", "") != "2.0")
    r.fail("asset.version", "must be \"2.0\"");
  if (!r.doc.contains("materials") || !r.doc["materials"].is_array() || r.doc["materials"].empty())
    r.fail("materials", "holds no material");
  const json& mat = r.doc["materials"][0];
  const json pbr = mat.value("pbrMetallicRoughness", json::object());
  const std::optional<ImageRgba8> base = r.texture(pbr, "baseColorTexture", "materials[0].pbrMetallicRoughness");
  const std::optional<ImageRgba8> mr = r.texture(pbr, "metallicRoughnessTexture", "materials[0].pbrMetallicRoughness");
  const std::optional<ImageRgba8> normal = r.texture(mat, "normalTexture", "materials[0]");
  const json sheenExt = mat.contains("extensions") && mat["extensions"].contains("KHR_materials_sheen")
                            ? mat["extensions"]["KHR_materials_sheen"]
                            : json();
  const std::string sheenField = "materials[0].extensions.KHR_materials_sheen";
  const std::optional<ImageRgba8> sheenColor =
      sheenExt.is_object() ? r.texture(sheenExt, "sheenColorTexture", sheenField) : std::nullopt;
  const std::optional<ImageRgba8> sheenRoughness =
      sheenExt.is_object() ? r.texture(sheenExt, "sheenRoughnessTexture", sheenField) : std::nullopt;
  const json specExt = mat.contains("extensions") && mat["extensions"].contains("KHR_materials_specular")
                           ? mat["extensions"]["KHR_materials_specular"]
                           : json();
  const std::string specField = "materials[0].extensions.KHR_materials_specular";
  double specularFactor = 1;
  if (specExt.is_object()) {
    if (number(specExt, "specularFactor", 1) != 1 || specExt.contains("specularTexture"))
      r.fail(specField, "only specularFactor 1 without a specularTexture is read (the colour scales F0)");
    const json c = specExt.value("specularColorFactor", json::array({1.0, 1.0, 1.0}));
    if (!c.is_array() || c.size() != 3 || !c[0].is_number() || c[0] != c[1] || c[0] != c[2])
      r.fail(specField + ".specularColorFactor", "only a grey specular colour (3 equal numbers) is read");
    specularFactor = c[0].get<double>();
  }
  const std::optional<ImageRgba8> specularColor =
      specExt.is_object() ? r.texture(specExt, "specularColorTexture", specField) : std::nullopt;
  int width = 1, height = 1;
  const std::optional<ImageRgba8>* all[] = {&base, &mr, &normal, &sheenColor, &sheenRoughness, &specularColor};
  for (const auto* img : all)
    if (*img) width = (*img)->width, height = (*img)->height;
  for (const auto* img : all)
    if (*img && ((*img)->width != width || (*img)->height != height))
      r.fail("materials[0]", "its textures differ in size (" + std::to_string((*img)->width) + " x " +
                                 std::to_string((*img)->height) + " against " + std::to_string(width) + " x " +
                                 std::to_string(height) + ")");
  const std::size_t n = static_cast<std::size_t>(width) * height;
  TextureSet t;
  t.width = width, t.height = height;
  t.baseColor = rgbOf(base, n, 255);
  t.metallicRoughness = rgbOf(mr, n, 255);
  t.normal = rgbOf(normal, n, 0);
  if (!normal)
    for (std::size_t i = 0; i < n; ++i) t.normal[3 * i] = t.normal[3 * i + 1] = 128, t.normal[3 * i + 2] = 255;
  if (sheenExt.is_object()) {  // colour x factor in RGB, roughness x factor from the roughness texture's alpha
    t.sheen.assign(4 * n, 255);
    for (std::size_t i = 0; i < n; ++i) {
      for (int c = 0; c < 3; ++c) t.sheen[4 * i + c] = sheenColor ? sheenColor->rgba[4 * i + c] : 255;
      t.sheen[4 * i + 3] = sheenRoughness ? sheenRoughness->rgba[4 * i + 3] : 255;
    }
  }
  if (specExt.is_object()) {  // the texture's first channel (a grey colour), or the factor alone
    t.specular = specularColor ? rgbOf(specularColor, n, 255) : std::vector<std::uint8_t>(3 * n, 255);
    t.specularColorFactor = specularFactor;
  }
  double exposure = 1;
  if (mat.contains("extras") && mat["extras"].contains("nbtf")) exposure = number(mat["extras"]["nbtf"], "exposure", 1);
  if (!(exposure > 0)) r.fail("materials[0].extras.nbtf.exposure", "must be positive");
  GltfMaterial m = dequantize(t, exposure, path);
  // The factors multiply the textures (the specification's rule).
  const json baseFactor = pbr.value("baseColorFactor", json::array({1.0, 1.0, 1.0, 1.0}));
  if (!baseFactor.is_array() || baseFactor.size() != 4) r.fail("materials[0].pbrMetallicRoughness.baseColorFactor", "needs 4 numbers");
  const double metallic = number(pbr, "metallicFactor", 1), roughness = number(pbr, "roughnessFactor", 1);
  const double normalScale = mat.contains("normalTexture") ? number(mat["normalTexture"], "scale", 1) : 1;
  const json sheenFactor = sheenExt.is_object() ? sheenExt.value("sheenColorFactor", json::array({0.0, 0.0, 0.0})) : json();
  if (sheenExt.is_object() && (!sheenFactor.is_array() || sheenFactor.size() != 3))
    r.fail(sheenField + ".sheenColorFactor", "needs 3 numbers");
  const double sheenRoughnessFactor = sheenExt.is_object() ? number(sheenExt, "sheenRoughnessFactor", 0) : 0;
  for (TexelParams& p : m.texels) {
    for (int c = 0; c < 3; ++c) p.brdf.baseColor[c] *= baseFactor[c].get<double>();
    if (m.sheen) {
      for (int c = 0; c < 3; ++c) p.brdf.sheenColor[c] *= sheenFactor[c].get<double>();
      p.brdf.sheenRoughness *= sheenRoughnessFactor;
    }
    p.brdf.metallic *= metallic;
    p.brdf.roughness *= roughness;
    if (normalScale != 1) {
      Vec3 nm{p.normal[0] * normalScale, p.normal[1] * normalScale, p.normal[2]};
      const double len = std::sqrt(nm[0] * nm[0] + nm[1] * nm[1] + nm[2] * nm[2]);
      p.normal = {nm[0] / len, nm[1] / len, nm[2] / len};
    }
  }
  return m;
}

}  // namespace nbtf::gltf
