// The shader generator (src/shader/): the description, the textures, the manifest, the export
// folder, and the errors for what the shader cannot express. The generated GLSL runs in a
// browser in viewer_browser_test.cpp; the viewer page has viewer_page_test.cpp.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "shader/shader_export.h"
#include "shader/viewer_page.h"
#include "shader_test_materials.h"
#include "test_util.h"
#include "util/directions.h"

namespace nbtf {
namespace {

using testing::makeShaderClusteredMaterial;
using testing::makeShaderPcaMaterial;
using testing::makeShaderPerTexelMaterial;
using testing::readText;

const ShaderTexture* findTexture(const ShaderDecoder& s, const std::string& uniform) {
  for (const ShaderTexture& t : s.textures)
    if (t.uniform == uniform) return &t;
  return nullptr;
}

TEST(ShaderExport, ClusteredDescriptionFollowsTheFile) {
  const CompressedBtf m = makeShaderClusteredMaterial();
  const ShaderDecoder s = buildShaderDecoder(m, "dir/cl.nbtf", ShaderWeights::Texture);
  EXPECT_FALSE(s.description.weightsInUniformBlocks);
  EXPECT_TRUE(s.uniformBlocks.empty());
  const ShaderDecoderDescription& d = s.description;
  EXPECT_EQ(d.method, CodecMethod::ClusteredNeural);
  EXPECT_TRUE(d.idMap);
  EXPECT_EQ(d.encodingInputs, 20);
  EXPECT_EQ(d.planeFeatures, 3);
  EXPECT_EQ(d.directionInputs(), m.directionInputs());
  ASSERT_EQ(d.layers.size(), m.decoder.layers.size());
  for (std::size_t i = 0; i < d.layers.size(); ++i) {
    EXPECT_EQ(d.layers[i].in, m.decoder.layers[i].in);
    EXPECT_EQ(d.layers[i].out, m.decoder.layers[i].out);
  }
  EXPECT_EQ(d.modulationTerms, 2);
  EXPECT_EQ(d.modulationChannels, 3);
  for (const char* name : {"nbtf_weights", "nbtf_latents", "nbtf_ids", "nbtf_modulation", "nbtf_planes"}) {
    const ShaderTexture* t = findTexture(s, name);
    ASSERT_NE(t, nullptr) << name;
    EXPECT_EQ(t->data.size(), static_cast<std::size_t>(t->width) * t->height * 4) << name;
    EXPECT_LE(t->vec4s, static_cast<std::size_t>(t->width) * t->height) << name;
    EXPECT_LE(t->width, kShaderTextureSize);
    EXPECT_NE(s.glsl.find("uniform highp sampler2D " + std::string(name) + ";"), std::string::npos) << name;
  }
  EXPECT_NE(s.glsl.find("vec3 nbtf_decode(vec2 uv, vec3 light, vec3 view)"), std::string::npos);
  // The weights: layer 0's first group of 4 output rows (each padded to whole vec4s), then the
  // group's 4 biases; the groups one after the other.
  const ShaderTexture& w = *findTexture(s, "nbtf_weights");
  EXPECT_GT(w.height, 1);
  const DenseLayer& l0 = m.decoder.layers[0];
  const int in4 = d.layers[0].inVec4s();
  for (int r = 0; r < 4; ++r)
    for (int i = 0; i < l0.in; ++i) EXPECT_EQ(w.data[r * in4 * 4 + i], l0.weight[r * l0.in + i]);
  for (int r = 0; r < 4; ++r) EXPECT_EQ(w.data[16 * in4 + r], l0.bias[r]);
  EXPECT_EQ(w.data[4 * d.layers[0].groupVec4s() + 0], l0.weight[4 * l0.in]);  // group 1, row 4
  ASSERT_EQ(d.layers[0].segments.size(), 1u);
  EXPECT_EQ(d.layers[0].segments[0].block, -1);
  // Ids: four texels per RGBA texel, as floats.
  const ShaderTexture& ids = *findTexture(s, "nbtf_ids");
  for (int t = 0; t < m.numTexels(); ++t) EXPECT_EQ(ids.data[t], static_cast<float>(m.ids[t]));
  EXPECT_GT(s.cost.multiplyAdds, 106.0 * (8 + 20 + 9) + 106.0 * 106);
  EXPECT_GT(s.cost.textureFetches, 0);
  EXPECT_GT(s.cost.transcendentals, 0);  // the Fourier inputs' sin and cos
}

TEST(ShaderExport, ClusterPlanesAreEachRowsOwnTexture) {
  // 5 features: two vec4 per grid point, the second padded with zeros.
  const CompressedBtf m = makeShaderClusteredMaterial(5);
  const ShaderDecoder s = buildShaderDecoder(m, "cp.nbtf");
  const ShaderDecoderDescription& d = s.description;
  EXPECT_EQ(d.clusterPlaneResolution, 4);
  EXPECT_EQ(d.clusterPlaneFeatures, 5);
  EXPECT_EQ(d.directionInputs(), m.directionInputs());
  EXPECT_EQ(d.directionInputs(), 20 + 3 * 3 + 3 * 5);
  const ShaderTexture* t = findTexture(s, "nbtf_cluster_planes");
  ASSERT_NE(t, nullptr);
  const int points = 3 * 4 * 4;  // per row
  EXPECT_EQ(t->vec4s, static_cast<std::size_t>(m.latentRows) * points * 2);
  // Row r, point q, feature f at vec4 (r x points + q) x 2 + f / 4, component f % 4.
  for (int r : {0, 2, m.latentRows - 1})
    for (int q : {0, 17, points - 1})
      for (int f = 0; f < 8; ++f) {
        const float want = f < 5 ? m.clusterPlanes.rowValues(r)[q * 5 + f] : 0.0f;
        EXPECT_EQ(t->data[((static_cast<std::size_t>(r) * points + q) * 2) * 4 + f], want)
            << "row " << r << " point " << q << " feature " << f;
      }
  // The lookup starts at the texel's own row and fills the inputs after the shared planes'.
  EXPECT_NE(s.glsl.find("int base = row * " + std::to_string(points * 2) + ";"), std::string::npos) << s.glsl;
  const int first = m.latentDim + 20 + 3 * 3;
  const std::string firstInput = "a[" + std::to_string(first / 4) + "]." + "xyzw"[first % 4] + " = f0.x;";
  EXPECT_NE(s.glsl.find(firstInput), std::string::npos) << firstInput;
  const nlohmann::json manifest = nlohmann::json::parse(shaderManifestJson(s));
  EXPECT_EQ(manifest["material"]["cluster_planes"]["resolution"], 4);
  EXPECT_EQ(manifest["material"]["cluster_planes"]["features"], 5);
  // Each set of planes costs its own taps: 3 planes x 4 taps x 2 vec4 more fetches (the weights
  // in textures, so layer 0's wider rows add their own reads: 4 x groups per vec4 of inputs).
  const ShaderDecoder withPlanes = buildShaderDecoder(m, "cp.nbtf", ShaderWeights::Texture);
  const ShaderDecoder plain = buildShaderDecoder(makeShaderClusteredMaterial(), "plain.nbtf", ShaderWeights::Texture);
  const int widerRows = withPlanes.description.layers[0].inVec4s() - plain.description.layers[0].inVec4s();
  EXPECT_EQ(withPlanes.cost.textureFetches - plain.cost.textureFetches,
            3 * 4 * 2 + widerRows * 4 * d.layers[0].groups());
  // In the per-texel mode every texel is its own row.
  const CompressedBtf perTexel =
      testing::makeDecoderMaterial(0, {24, 16}, 6, 5, 13, DirectionEncoding::StereographicFourier2, 0, 2);
  const ShaderDecoder p = buildShaderDecoder(perTexel, "ptcp.nbtf");
  ASSERT_NE(findTexture(p, "nbtf_cluster_planes"), nullptr);
  EXPECT_EQ(findTexture(p, "nbtf_cluster_planes")->vec4s, static_cast<std::size_t>(6 * 5 * points));
  EXPECT_NE(p.glsl.find("int row = t;"), std::string::npos);
}

TEST(ShaderExport, WeightsInUniformBlocksWhenTheyFit) {
  const CompressedBtf m = makeShaderClusteredMaterial();
  const ShaderDecoder s = buildShaderDecoder(m, "cl.nbtf");  // auto
  EXPECT_TRUE(s.description.weightsInUniformBlocks);
  EXPECT_EQ(findTexture(s, "nbtf_weights"), nullptr);
  ASSERT_GE(s.uniformBlocks.size(), 2u);  // 106-wide layers: more than one block, a layer split across two
  EXPECT_LE(s.uniformBlocks.size(), static_cast<std::size_t>(kMaxShaderUniformBlocks));
  std::size_t vec4s = 0;
  for (const ShaderUniformBlock& b : s.uniformBlocks) {
    EXPECT_LE(b.vec4s, static_cast<std::size_t>(kShaderUniformBlockVec4s));
    EXPECT_EQ(b.data.size(), 4 * b.vec4s);
    EXPECT_NE(s.glsl.find("uniform " + b.block + " { vec4 " + b.array + "[" + std::to_string(b.vec4s) + "]; }"),
              std::string::npos);
    vec4s += b.vec4s;
  }
  // Every group in exactly one segment; segments in order.
  std::size_t groupVec4s = 0;
  for (const ShaderLayer& l : s.description.layers) {
    int next = 0;
    for (const ShaderLayerSegment& seg : l.segments) {
      EXPECT_EQ(seg.firstGroup, next);
      EXPECT_GE(seg.block, 0);
      EXPECT_LE(seg.offset + (seg.endGroup - seg.firstGroup) * l.groupVec4s(), kShaderUniformBlockVec4s);
      next = seg.endGroup;
    }
    EXPECT_EQ(next, l.groups());
    groupVec4s += static_cast<std::size_t>(l.groups()) * l.groupVec4s();
  }
  EXPECT_EQ(vec4s, groupVec4s);
  EXPECT_EQ(s.uniformBlocks[0].data[0], m.decoder.layers[0].weight[0]);
  EXPECT_EQ(s.cost.textureFetches + s.cost.uniformLoads,
            buildShaderDecoder(m, "cl.nbtf", ShaderWeights::Texture).cost.textureFetches);
  // A decoder too large for 12 blocks: textures under auto, an error when blocks are demanded.
  const CompressedBtf big = testing::makeDecoderMaterial(3, {256, 256, 256});
  EXPECT_FALSE(buildShaderDecoder(big, "big.nbtf").description.weightsInUniformBlocks);
  test::expectErrorContaining([&] { buildShaderDecoder(big, "big.nbtf", ShaderWeights::UniformBlocks); },
                              {"big.nbtf", "uniform blocks", "12"});
  EXPECT_EQ(parseShaderWeights("uniform-blocks"), ShaderWeights::UniformBlocks);
  test::expectErrorContaining([] { parseShaderWeights("ubo"); }, {"ubo", "auto, texture or uniform-blocks"});
}

TEST(ShaderExport, PerTexelAndPcaHaveTheirOwnTextures) {
  const ShaderDecoder p = buildShaderDecoder(makeShaderPerTexelMaterial(), "pt.nbtf");
  EXPECT_FALSE(p.description.idMap);
  EXPECT_EQ(findTexture(p, "nbtf_ids"), nullptr);
  EXPECT_EQ(findTexture(p, "nbtf_modulation"), nullptr);
  EXPECT_NE(p.glsl.find("exp(-("), std::string::npos);  // the sigmoid layer
  const CompressedBtf pcaMaterial = makeShaderPcaMaterial();
  const ShaderDecoder q = buildShaderDecoder(pcaMaterial, "pca.nbtf");
  EXPECT_EQ(q.description.pcaComponents, 4);
  EXPECT_EQ(q.description.lights, 19);
  const ShaderTexture* rows = findTexture(q, "nbtf_pca_rows");
  ASSERT_NE(rows, nullptr);
  // Row 3 x image + channel: [mean, basis], two vec4 for 4 components.
  EXPECT_EQ(rows->vec4s, static_cast<std::size_t>(3 * pcaMaterial.numImages() * 2));
  EXPECT_EQ(rows->data[8 * 5], pcaMaterial.pcaMean[5]);
  EXPECT_EQ(rows->data[8 * 5 + 1], pcaMaterial.pcaBasis[5 * 4]);
  const ShaderTexture* k = findTexture(q, "nbtf_pca_coefficients");
  ASSERT_NE(k, nullptr);
  EXPECT_EQ(k->data[0], 1.0f);
  EXPECT_EQ(k->data[1], pcaMaterial.latents[0]);
  ASSERT_NE(findTexture(q, "nbtf_directions"), nullptr);
  EXPECT_EQ(findTexture(q, "nbtf_directions")->vec4s, 38u);
}

TEST(ShaderExport, ExportFolderHoldsWhatTheManifestLists) {
  test::TempDir tmp;
  const ShaderDecoder s = buildShaderDecoder(makeShaderClusteredMaterial(), "cl.nbtf");
  const std::string dir = tmp / "out/shader";
  writeShaderExport(s, dir);
  const auto manifest = nlohmann::json::parse(readText(dir + "/manifest.json"));
  EXPECT_EQ(manifest["format"], "nbtf-shader");
  EXPECT_EQ(manifest["glsl"], "nbtf_decoder.glsl");
  EXPECT_EQ(readText(dir + "/nbtf_decoder.glsl"), s.glsl);
  ASSERT_EQ(manifest["textures"].size(), s.textures.size());
  ASSERT_EQ(manifest["uniform_blocks"].size(), s.uniformBlocks.size());
  EXPECT_EQ(manifest["weights"], "uniform-blocks");
  for (const auto& b : manifest["uniform_blocks"]) {
    const std::string file = dir + "/" + b["file"].get<std::string>();
    ASSERT_TRUE(std::filesystem::exists(file)) << file;
    EXPECT_EQ(std::filesystem::file_size(file), b["vec4s"].get<std::size_t>() * 16);
    EXPECT_NE(s.glsl.find(b["block"].get<std::string>()), std::string::npos);
  }
  std::size_t files = 0;
  for (const auto& t : manifest["textures"]) {
    const std::string file = dir + "/" + t["file"].get<std::string>();
    ASSERT_TRUE(std::filesystem::exists(file)) << file;
    EXPECT_EQ(std::filesystem::file_size(file), t["width"].get<std::size_t>() * t["height"].get<std::size_t>() * 16);
    EXPECT_EQ(t["bytes"].get<std::size_t>(), std::filesystem::file_size(file));
    EXPECT_EQ(t["internal_format"], "RGBA32F");
    EXPECT_NE(s.glsl.find(t["uniform"].get<std::string>()), std::string::npos);
    const ShaderTexture* mine = findTexture(s, t["uniform"].get<std::string>());
    ASSERT_NE(mine, nullptr);
    std::vector<float> back(mine->data.size());
    std::ifstream(file, std::ios::binary).read(reinterpret_cast<char*>(back.data()), back.size() * 4);
    EXPECT_EQ(back, mine->data);
    ++files;
  }
  // Exactly the listed files plus the GLSL and the manifest; no temporary left beside.
  std::size_t present = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) present += e.is_regular_file();
  EXPECT_EQ(present, files + s.uniformBlocks.size() + 2);
  std::size_t siblings = 0;
  for (const auto& e : std::filesystem::directory_iterator(tmp / "out")) siblings += 1, (void)e;
  EXPECT_EQ(siblings, 1u);
  // Exporting again replaces the folder.
  writeShaderExport(buildShaderDecoder(makeShaderPcaMaterial(), "pca.nbtf"), dir);
  EXPECT_EQ(nlohmann::json::parse(readText(dir + "/manifest.json"))["material"]["method"], "pca");
  EXPECT_FALSE(std::filesystem::exists(dir + "/NbtfWeights0.f32"));
}

TEST(ShaderExport, WhatTheShaderCannotExpressIsRefusedAndNothingIsWritten) {
  test::TempDir tmp;
  CompressedBtf wide = testing::makeDecoderMaterial(3, {300, 16});
  test::expectErrorContaining([&] { buildShaderDecoder(wide, "wide.nbtf"); },
                              {"wide.nbtf", "decoder layer 0", "300", "256", "cannot express"});
  const std::string file = tmp / "wide.nbtf";
  writeNbtf(file, wide);
  const auto r = test::runNbtf("export-shader " + file + " -o " + tmp / "out");
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("decoder layer 0"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(tmp / "out"));
  const auto page = test::runNbtf("view " + file + " -o " + tmp / "wide.html");
  EXPECT_EQ(page.exitCode, 1) << page.output;
  EXPECT_NE(page.output.find("wider than the 256"), std::string::npos) << page.output;
  EXPECT_FALSE(std::filesystem::exists(tmp / "wide.html"));
  // A folder that is not an earlier export is never replaced.
  std::filesystem::create_directories(tmp / "mine");
  std::ofstream(tmp / "mine/notes.txt") << "keep";
  test::expectErrorContaining(
      [&] { writeShaderExport(buildShaderDecoder(makeShaderPerTexelMaterial(), "pt.nbtf"), tmp / "mine"); },
      {"mine", "not a shader export"});
  EXPECT_EQ(readText(tmp / "mine/notes.txt"), "keep");
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(tmp.path()), {}), 2);  // wide.nbtf, mine
}

TEST(ShaderExport, CommandWritesTheFolder) {
  test::TempDir tmp;
  const std::string file = tmp / "pt.nbtf";
  writeNbtf(file, makeShaderPerTexelMaterial());
  const auto r = test::runNbtf("export-shader " + file + " -o " + tmp / "glsl");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("texture fetches"), std::string::npos) << r.output;
  const auto manifest = nlohmann::json::parse(readText(tmp / "glsl/manifest.json"));
  EXPECT_EQ(manifest["material"]["method"], "per-texel-neural");
  EXPECT_EQ(manifest["material"]["direction_encoding"], "stereographic+half");
  EXPECT_EQ(manifest["material"]["layers"][0]["activation"], "sigmoid");
  // The folder gets the mode every output folder gets (0777 less the umask), not mkdtemp's 0700.
  const mode_t mask = ::umask(0);
  ::umask(mask);
  struct stat st;
  ASSERT_EQ(::stat((tmp / "glsl").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0777 & ~mask);
}

}  // namespace
}  // namespace nbtf
