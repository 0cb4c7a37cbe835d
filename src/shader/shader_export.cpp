#include "shader/shader_export.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>

#include "codec/pca_model.h"
#include "codec/texel_modulation.h"
#include "util/error.h"
#include "util/output_folder.h"

namespace nbtf {
namespace {

constexpr std::size_t kMaxTextureVec4s = static_cast<std::size_t>(kShaderTextureSize) * kShaderTextureSize;
// The PCA interpolation's neighbours (codec/pca_model.h): K blended, K + 1 looked at.
constexpr int kPcaKeep = kPcaNeighbours + 1;

int vec4sOf(int values) { return (values + 3) / 4; }

// A GLSL float literal that reads back as exactly `v` (9 significant digits).
std::string lit(float v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.9g", static_cast<double>(v));
  std::string s = buf;
  if (s.find_first_of(".eEn") == std::string::npos) s += ".0";
  return s;
}

// "a3[1].z": component i of a vec4 array.
std::string comp(const std::string& array, int i) {
  static const char* xyzw[] = {"x", "y", "z", "w"};
  return array + "[" + std::to_string(i / 4) + "]." + xyzw[i % 4];
}

// A flat vec4 array as a texture of at most kShaderTextureSize columns.
ShaderTexture makeTexture(const std::string& name, const std::string& uniform, const std::string& contents,
                          const std::vector<float>& values) {
  ShaderTexture t;
  t.uniform = uniform;
  t.file = uniform + ".f32";
  t.contents = contents;
  t.vec4s = std::max<std::size_t>(1, (values.size() + 3) / 4);
  if (t.vec4s > kMaxTextureVec4s)
    throw Error(name + ": " + contents + " need " + std::to_string(t.vec4s) + " RGBA texels, more than the " +
                std::to_string(kShaderTextureSize) + " x " + std::to_string(kShaderTextureSize) +
                " texture every WebGL2 / OpenGL ES 3.0 implementation supports; the shader cannot hold this file");
  t.width = static_cast<int>(std::min<std::size_t>(kShaderTextureSize, t.vec4s));
  t.height = static_cast<int>((t.vec4s + t.width - 1) / t.width);
  t.data.assign(static_cast<std::size_t>(t.width) * t.height * 4, 0.0f);
  std::copy(values.begin(), values.end(), t.data.begin());
  return t;
}

// ---- Packing the data ---------------------------------------------------------------------

// Rows of `count` values each, every row padded to whole vec4s.
std::vector<float> paddedRows(const float* values, std::size_t rows, int count, int rowVec4s) {
  std::vector<float> out(rows * rowVec4s * 4, 0.0f);
  for (std::size_t r = 0; r < rows; ++r) std::copy_n(values + r * count, count, out.begin() + r * rowVec4s * 4);
  return out;
}

std::string activationGlsl(Activation a, const std::string& name, const std::string& x) {
  switch (a) {
    case Activation::None: return x;
    case Activation::Relu: return "max(" + x + ", vec4(0.0))";
    case Activation::Sigmoid: return "vec4(1.0) / (vec4(1.0) + exp(-(" + x + ")))";
  }
  throw Error(name + ": the shader has no form of activation code " + std::to_string(static_cast<int>(a)));
}

// ---- GLSL pieces --------------------------------------------------------------------------

std::string fetchFunctions(const std::vector<ShaderTexture>& textures) {
  std::ostringstream s;
  for (const ShaderTexture& t : textures) {
    s << "uniform highp sampler2D " << t.uniform << ";  // " << t.contents << ", " << t.width << " x " << t.height
      << " RGBA32F\n";
  }
  s << "\n";
  for (const ShaderTexture& t : textures) {
    s << "vec4 " << t.uniform << "_at(int i) { return texelFetch(" << t.uniform << ", ivec2(i % " << t.width
      << ", i / " << t.width << "), 0); }\n";
  }
  return s.str();
}

// texel index of uv: floor(u W) mod W, floor(v H) mod H (the texture tiles), as NbtfDecoder::texelOfUv.
std::string texelFunction(int width, int height) {
  std::ostringstream s;
  s << "const int NBTF_WIDTH = " << width << ";\nconst int NBTF_HEIGHT = " << height << ";\n"
    << "const float NBTF_PI = 3.14159265358979;\n\n"
    << "int nbtf_texel(vec2 uv) {\n"
    << "  vec2 size = vec2(float(NBTF_WIDTH), float(NBTF_HEIGHT));\n"
    << "  vec2 f = floor(uv * size);\n"
    << "  ivec2 t = clamp(ivec2(f - size * floor(f / size)), ivec2(0), ivec2(NBTF_WIDTH - 1, NBTF_HEIGHT - 1));\n"
    << "  return t.y * NBTF_WIDTH + t.x;\n}\n\n"
    << "// x / (1 + z), y / (1 + z): the stereographic projection of a unit vector (eq. 7-9).\n"
    << "vec2 nbtf_stereo(vec3 d) { return d.xy / (1.0 + d.z); }\n\n";
  return s.str();
}

// The fixed direction inputs into layer 0's input array `a` from index `first`. An encoding
// this generator has no stage for (one added to util/directions.h after it) is refused, never
// half-written: the inputs emitted must be exactly directionInputCount(encoding).
std::string encodingGlsl(DirectionEncoding encoding, int first, const std::string& name) {
  switch (encoding) {
    case DirectionEncoding::Stereographic:
    case DirectionEncoding::StereographicHalf:
    case DirectionEncoding::StereographicFourier:
    case DirectionEncoding::StereographicFourier2: break;
    default:
      throw Error(name + ": direction encoding \"" + directionEncodingName(encoding) + "\" (code " +
                  std::to_string(static_cast<int>(encoding)) + ") has no GLSL form in this build");
  }
  std::ostringstream s;
  int i = first;
  auto put = [&](const std::string& value) { s << "  " << comp("a", i++) << " = " << value << ";\n"; };
  s << "  // Direction encoding: " << directionEncodingName(encoding) << " (" << directionInputCount(encoding)
    << " inputs)\n";
  s << "  vec2 sl = nbtf_stereo(light), sv = nbtf_stereo(view);\n";
  put("sl.x"), put("sl.y"), put("sv.x"), put("sv.y");
  if (encoding == DirectionEncoding::StereographicHalf) {
    s << "  vec3 hs = light + view;\n  float hn = length(hs);\n"
      << "  vec3 h = hn > 0.0 ? hs / hn : vec3(0.0, 0.0, 1.0);\n";
    put("h.x"), put("h.y"), put("h.z"), put("dot(light, h)");
  }
  const int octaves = fourierOctaves(encoding);
  if (octaves > 0) {
    // sin and cos of pi c, then each octave doubles the angle, as util/directions.cpp.
    s << "  float st[4] = float[4](sl.x, sl.y, sv.x, sv.y);\n";
    for (int c = 0; c < 4; ++c) {
      s << "  {\n    float sn = sin(NBTF_PI * st[" << c << "]), cs = cos(NBTF_PI * st[" << c << "]);\n";
      for (int o = 0; o < octaves; ++o) {
        s << "    " << comp("a", i) << " = sn;\n    " << comp("a", i + 1) << " = cs;\n";
        i += 2;
        if (o + 1 < octaves) s << "    { float s2 = 2.0 * sn * cs, c2 = cs * cs - sn * sn; sn = s2; cs = c2; }\n";
      }
      s << "  }\n";
    }
  }
  if (i - first != directionInputCount(encoding))
    throw Error(name + ": direction encoding \"" + directionEncodingName(encoding) + "\": the shader emits " +
                std::to_string(i - first) + " inputs, the decoder takes " +
                std::to_string(directionInputCount(encoding)) + "; it has no GLSL form in this build");
  return s.str();
}

// The three points every set of planes samples (util/direction_planes.cpp): the stereographic
// projections of light, view and the half vector (the normal when light = -view).
std::string planePointsGlsl() {
  return "  vec3 hp = light + view;\n  float hl = length(hp);\n"
         "  vec2 pts[3] = vec2[3](nbtf_stereo(light), nbtf_stereo(view), hl > 1e-12 ? nbtf_stereo(hp / hl) : vec2(0.0));\n";
}

// One set of planes' 3 F features at `pts` into `a` from index `first`, bilinear with the
// clamped taps of util/direction_planes.cpp. `fetch` reads the texture; `rowBase` is the GLSL
// index of the set's first vec4 ("0" for the shared planes, "row * N" for cluster planes).
std::string planesGlsl(const std::string& what, int resolution, int features, int first, const std::string& fetch,
                       const std::string& rowBase) {
  std::ostringstream s;
  const int f4 = vec4sOf(features);
  s << "  // " << what << ": light, view, half vector; " << resolution << " x " << resolution << " points x "
    << features << " features, bilinear\n";
  s << "  {\n    int base = " << rowBase << ";\n";
  for (int p = 0; p < 3; ++p) {
    s << "    {\n      vec2 g = clamp((pts[" << p << "] + 1.0) * " << lit(0.5f * static_cast<float>(resolution - 1))
      << ", vec2(0.0), vec2(" << lit(static_cast<float>(resolution - 1)) << "));\n"
      << "      ivec2 c = min(ivec2(g), ivec2(" << resolution - 2 << "));\n"
      << "      vec2 fr = g - vec2(c);\n"
      << "      int i00 = base + ((" << p << " * " << resolution << " + c.y) * " << resolution << " + c.x) * " << f4
      << ";\n";
    for (int j = 0; j < f4; ++j) {
      s << "      vec4 f" << j << " = (1.0 - fr.x) * (1.0 - fr.y) * " << fetch << "(i00 + " << j << ")"
        << " + fr.x * (1.0 - fr.y) * " << fetch << "(i00 + " << f4 + j << ")"
        << " + (1.0 - fr.x) * fr.y * " << fetch << "(i00 + " << resolution * f4 + j << ")"
        << " + fr.x * fr.y * " << fetch << "(i00 + " << (resolution + 1) * f4 + j << ");\n";
    }
    for (int f = 0; f < features; ++f) {
      static const char* xyzw[] = {"x", "y", "z", "w"};
      s << "      " << comp("a", first + p * features + f) << " = f" << f / 4 << "." << xyzw[f % 4] << ";\n";
    }
    s << "    }\n";
  }
  s << "  }\n";
  return s.str();
}

// What one set of planes costs per pixel: per plane the grid position and 4 taps of f4 vec4s.
void addPlanesCost(int features, ShaderCost& c) {
  const int f4 = vec4sOf(features);
  c.otherOps += 3 * (6 + 8);
  c.textureFetches += 3 * 4 * f4;
  c.multiplyAdds += 3 * 4 * 4 * f4;
}

// ---- The neural decoder -------------------------------------------------------------------

// The description of a neural material's shader: encoding, planes, latents, id map, modulation.
void describeNeural(const CompressedBtf& m, const std::string& name, ShaderDecoderDescription& d) {
  if (!isDirectionEncoding(static_cast<int>(m.directionEncoding)))
    throw Error(name + ": direction encoding code " + std::to_string(static_cast<int>(m.directionEncoding)) +
                " has no GLSL form in this build");
  d.encoding = m.directionEncoding;
  d.encodingInputs = directionInputCount(m.directionEncoding);
  d.planeResolution = m.planes.empty() ? 0 : m.planes.resolution;
  d.planeFeatures = m.planes.empty() ? 0 : m.planes.features;
  d.clusterPlaneResolution = m.clusterPlanes.empty() ? 0 : m.clusterPlanes.resolution;
  d.clusterPlaneFeatures = m.clusterPlanes.empty() ? 0 : m.clusterPlanes.features;
  d.latentDim = m.latentDim;
  d.latentRows = m.latentRows;
  d.idMap = m.method == CodecMethod::ClusteredNeural;
  d.modulationTerms = m.modulation.empty() ? 0 : m.modulation.terms;
  d.modulationChannels = m.modulation.empty() ? 1 : m.modulation.channels;
  if (d.idMap && m.latentRows > (1 << 24))
    throw Error(name + ": " + std::to_string(m.latentRows) +
                " clusters: the shader's id map holds ids as float32 (exact up to 2^24)");
}

// The layers, in groups of 4 output rows: the rows' weights (each padded to whole vec4s; rows past
// `out` are zero), then the group's 4 biases. Every group's vec4s, layer by layer; d.layers filled.
std::vector<std::vector<float>> layerGroups(const CompressedBtf& m, const std::string& name,
                                            ShaderDecoderDescription& d) {
  std::vector<std::vector<float>> groups;  // every group's vec4s, layer by layer
  for (std::size_t li = 0; li < m.decoder.layers.size(); ++li) {
    const DenseLayer& l = m.decoder.layers[li];
    const std::string which = "decoder layer " + std::to_string(li);
    if (l.in > kMaxShaderLayerWidth || l.out > kMaxShaderLayerWidth)
      throw Error(name + ": " + which + " is " + std::to_string(l.out) + " x " + std::to_string(l.in) +
                  ", wider than the " + std::to_string(kMaxShaderLayerWidth) +
                  " values a fragment shader keeps in registers; the shader cannot express this decoder");
    activationGlsl(l.activation, name + ": " + which, "x");  // throws for an activation it has no form of
    ShaderLayer s;
    s.in = l.in, s.out = l.out, s.activation = l.activation;
    const int in4 = s.inVec4s();
    for (int g = 0; g < s.groups(); ++g) {
      std::vector<float> group(static_cast<std::size_t>(s.groupVec4s()) * 4, 0.0f);
      for (int r = 0; r < 4 && 4 * g + r < l.out; ++r) {
        const int o = 4 * g + r;
        std::copy_n(l.weight.data() + static_cast<std::size_t>(o) * l.in, l.in,
                    group.begin() + static_cast<std::size_t>(r) * in4 * 4);
        group[static_cast<std::size_t>(4) * in4 * 4 + r] = l.bias[o];
      }
      groups.push_back(std::move(group));
    }
    d.layers.push_back(s);
  }
  return groups;
}

// The groups in the weights texture one after the other, or in uniform blocks packed greedily, a
// group never split across two blocks; each layer's segments say where its groups are.
void placeWeights(const std::vector<std::vector<float>>& groups, ShaderWeights weights, ShaderDecoder& out) {
  ShaderDecoderDescription& d = out.description;
  const std::string& name = out.name;
  std::size_t totalVec4s = 0;
  for (const auto& g : groups) totalVec4s += g.size() / 4;
  // Blocks the greedy packing needs.
  int blocksNeeded = 0;
  {
    std::size_t used = kShaderUniformBlockVec4s;
    for (const auto& g : groups) {
      if (used + g.size() / 4 > static_cast<std::size_t>(kShaderUniformBlockVec4s)) ++blocksNeeded, used = 0;
      used += g.size() / 4;
    }
  }
  if (weights == ShaderWeights::UniformBlocks && blocksNeeded > kMaxShaderUniformBlocks)
    throw Error(name + ": the decoder's " + std::to_string(totalVec4s) + " vec4 of weights need " +
                std::to_string(blocksNeeded) + " uniform blocks of 16 KiB, more than the " +
                std::to_string(kMaxShaderUniformBlocks) + " a fragment shader is guaranteed; use textures");
  d.weightsInUniformBlocks = weights == ShaderWeights::UniformBlocks ||
                             (weights == ShaderWeights::Auto && blocksNeeded <= kMaxShaderUniformBlocks);
  {
    std::vector<float> flat;  // the texture, or the block being filled
    std::size_t g = 0;
    auto closeBlock = [&] {
      ShaderUniformBlock b;
      const int index = static_cast<int>(out.uniformBlocks.size());
      b.block = "NbtfWeights" + std::to_string(index);
      b.array = "nbtf_wb" + std::to_string(index);
      b.file = b.block + ".f32";
      b.vec4s = flat.size() / 4;
      b.data = std::move(flat);
      flat.clear();
      out.uniformBlocks.push_back(std::move(b));
    };
    for (ShaderLayer& layer : d.layers) {
      for (int k = 0; k < layer.groups(); ++k, ++g) {
        const std::size_t size = groups[g].size() / 4;
        if (d.weightsInUniformBlocks && flat.size() / 4 + size > static_cast<std::size_t>(kShaderUniformBlockVec4s))
          closeBlock();
        const int block = d.weightsInUniformBlocks ? static_cast<int>(out.uniformBlocks.size()) : -1;
        if (layer.segments.empty() || layer.segments.back().block != block)
          layer.segments.push_back({k, k, block, static_cast<int>(flat.size() / 4)});
        layer.segments.back().endGroup = k + 1;
        flat.insert(flat.end(), groups[g].begin(), groups[g].end());
      }
    }
    if (d.weightsInUniformBlocks) closeBlock();
    else out.textures.push_back(makeTexture(name, "nbtf_weights", "decoder weights and biases", flat));
  }
}

// The latents, the id map, the modulation coefficients and the planes as textures.
void addNeuralTextures(const CompressedBtf& m, ShaderDecoder& out) {
  const ShaderDecoderDescription& d = out.description;
  const std::string& name = out.name;
  const int z4 = vec4sOf(m.latentDim);
  out.textures.push_back(makeTexture(name, "nbtf_latents",
                                     "latents (" + std::to_string(m.latentRows) + " rows x " + std::to_string(z4) + " vec4)",
                                     paddedRows(m.latents.data(), m.latentRows, m.latentDim, z4)));
  if (d.idMap) {
    std::vector<float> ids(m.ids.begin(), m.ids.end());
    out.textures.push_back(makeTexture(name, "nbtf_ids", "texel -> latent row (4 texels per RGBA texel)", ids));
  }
  const int columns = d.modulationTerms * d.modulationChannels, e4 = vec4sOf(columns);
  if (d.modulationTerms > 0) {
    const std::vector<float> e = dequantizeTexelCoefficients(m.modulation);
    out.textures.push_back(makeTexture(name, "nbtf_modulation",
                                       "per-texel modulation coefficients (dequantized, " + std::to_string(e4) +
                                           " vec4 per texel)",
                                       paddedRows(e.data(), m.numTexels(), columns, e4)));
  }
  const int f4 = vec4sOf(d.planeFeatures);
  if (d.planeFeatures > 0) {
    const std::size_t points = static_cast<std::size_t>(3) * d.planeResolution * d.planeResolution;
    out.textures.push_back(makeTexture(name, "nbtf_planes",
                                       "direction planes ([plane][y][x], " + std::to_string(f4) + " vec4 per point)",
                                       paddedRows(m.planes.values.data(), points, d.planeFeatures, f4)));
  }
  const int g4 = vec4sOf(d.clusterPlaneFeatures);
  const std::size_t clusterPoints = static_cast<std::size_t>(3) * d.clusterPlaneResolution * d.clusterPlaneResolution;
  if (d.clusterPlaneFeatures > 0)
    out.textures.push_back(makeTexture(name, "nbtf_cluster_planes",
                                       "cluster planes (" + std::to_string(m.clusterPlanes.rows) +
                                           " latent rows x [plane][y][x], " + std::to_string(g4) + " vec4 per point)",
                                       paddedRows(m.clusterPlanes.values.data(), m.clusterPlanes.rows * clusterPoints,
                                                  d.clusterPlaneFeatures, g4)));
}

// Layer 0's input: the latent of the texel's row, then the direction inputs and the planes' features.
std::string neuralInputGlsl(const CompressedBtf& m, const ShaderDecoder& out) {
  const ShaderDecoderDescription& d = out.description;
  const std::string& name = out.name;
  const int z4 = vec4sOf(m.latentDim), g4 = vec4sOf(d.clusterPlaneFeatures);
  const std::size_t clusterPoints = static_cast<std::size_t>(3) * d.clusterPlaneResolution * d.clusterPlaneResolution;
  std::ostringstream s;
  s << fetchFunctions(out.textures);
  for (const ShaderUniformBlock& b : out.uniformBlocks)
    s << "layout(std140) uniform " << b.block << " { vec4 " << b.array << "[" << b.vec4s << "]; };  // decoder weights\n";
  s << "\n" << texelFunction(m.width, m.height);
  s << "vec3 nbtf_decode(vec2 uv, vec3 light, vec3 view) {\n"
    << "  int t = nbtf_texel(uv);\n";
  if (d.idMap)
    s << "  vec4 idq = nbtf_ids_at(t / 4);\n"
      << "  int row = int(dot(idq, vec4(equal(ivec4(t - 4 * (t / 4)), ivec4(0, 1, 2, 3)))) + 0.5);\n";
  else
    s << "  int row = t;\n";
  const int in0 = d.layers.front().in;
  s << "  // Layer 0's input: the latent, then the direction inputs\n"
    << "  vec4 a[" << vec4sOf(in0) << "];\n";
  for (int j = 0; j < vec4sOf(in0); ++j) s << "  a[" << j << "] = vec4(0.0);\n";
  for (int j = 0; j < z4; ++j) {
    s << "  {\n    vec4 z = nbtf_latents_at(row * " << z4 << " + " << j << ");\n";
    for (int c = 0; c < 4 && 4 * j + c < m.latentDim; ++c) {
      static const char* xyzw[] = {"x", "y", "z", "w"};
      s << "    " << comp("a", 4 * j + c) << " = z." << xyzw[c] << ";\n";
    }
    s << "  }\n";
  }
  s << encodingGlsl(d.encoding, m.latentDim, name);
  if (d.planeFeatures > 0 || d.clusterPlaneFeatures > 0) s << planePointsGlsl();
  if (d.planeFeatures > 0)
    s << planesGlsl("Direction planes", d.planeResolution, d.planeFeatures, m.latentDim + d.encodingInputs,
                    "nbtf_planes_at", "0");
  if (d.clusterPlaneFeatures > 0)
    s << planesGlsl("Cluster planes (the row's own)", d.clusterPlaneResolution, d.clusterPlaneFeatures,
                    m.latentDim + d.encodingInputs + 3 * d.planeFeatures, "nbtf_cluster_planes_at",
                    "row * " + std::to_string(clusterPoints * g4));
  return s.str();
}

// The dense layers: four output rows per step, a vec4 of inputs per read; the last one's output
// array is h<L-1>.
std::string denseLayersGlsl(const ShaderDecoder& out) {
  const ShaderDecoderDescription& d = out.description;
  const std::string& name = out.name;
  std::ostringstream s;
  std::string input = "a";
  for (std::size_t li = 0; li < d.layers.size(); ++li) {
    const ShaderLayer& l = d.layers[li];
    const std::string outName = "h" + std::to_string(li);
    const int in4 = l.inVec4s();
    s << "  // Layer " << li << ": " << l.in << " -> " << l.out << "\n"
      << "  vec4 " << outName << "[" << l.groups() << "];\n";
    for (const ShaderLayerSegment& seg : l.segments) {
      auto at = [&](const std::string& index) {
        return seg.block < 0 ? "nbtf_weights_at(" + index + ")"
                             : out.uniformBlocks[seg.block].array + "[" + index + "]";
      };
      s << "  for (int o = " << seg.firstGroup << "; o < " << seg.endGroup << "; ++o) {\n"
        << "    int w = " << seg.offset << " + (o - " << seg.firstGroup << ") * " << l.groupVec4s() << ";\n"
        << "    vec4 s0 = vec4(0.0), s1 = vec4(0.0), s2 = vec4(0.0), s3 = vec4(0.0);\n"
        << "    for (int j = 0; j < " << in4 << "; ++j) {\n"
        << "      vec4 x = " << input << "[j];\n"
        << "      s0 += " << at("w + j") << " * x;\n"
        << "      s1 += " << at("w + " + std::to_string(in4) + " + j") << " * x;\n"
        << "      s2 += " << at("w + " + std::to_string(2 * in4) + " + j") << " * x;\n"
        << "      s3 += " << at("w + " + std::to_string(3 * in4) + " + j") << " * x;\n"
        << "    }\n"
        << "    vec4 v = vec4(dot(s0, vec4(1.0)), dot(s1, vec4(1.0)), dot(s2, vec4(1.0)), dot(s3, vec4(1.0)))"
        << " + " << at("w + " + std::to_string(4 * in4)) << ";\n"
        << "    " << outName << "[o] = " << activationGlsl(l.activation, name, "v") << ";\n"
        << "  }\n";
    }
    input = outName;
  }
  return s.str();
}

// RGB from the last layer, or R RGB terms mixed by the texel's coefficients
// (codec/texel_modulation.h), x alpha.
std::string neuralOutputGlsl(const CompressedBtf& m, const ShaderDecoderDescription& d) {
  const std::string input = "h" + std::to_string(d.layers.size() - 1);
  const int e4 = vec4sOf(d.modulationTerms * d.modulationChannels);
  std::ostringstream s;
  if (d.modulationTerms == 0) {
    s << "  vec3 rgb = vec3(" << comp(input, 0) << ", " << comp(input, 1) << ", " << comp(input, 2) << ");\n";
  } else {
    s << "  // Per-texel modulation: " << modulationDescription(m.modulation) << "\n";
    s << "  vec4 e[" << e4 << "];\n";
    for (int j = 0; j < e4; ++j) s << "  e[" << j << "] = nbtf_modulation_at(t * " << e4 << " + " << j << ");\n";
    s << "  vec3 rgb = vec3(0.0);\n";
    static const char* rgbName[] = {"r", "g", "b"};
    for (int c = 0; c < 3; ++c) {
      for (int r = 0; r < d.modulationTerms; ++r) {
        const int col = r * d.modulationChannels + (d.modulationChannels == 1 ? 0 : c);
        s << "  rgb." << rgbName[c] << " += " << comp("e", col) << " * " << comp(input, 3 * r + c) << ";\n";
      }
    }
  }
  s << "  return rgb * " << lit(m.alpha) << ";  // x alpha: linear RGB\n}\n";
  return s.str();
}

// Cost per pixel (see ShaderCost).
void addNeuralCost(const CompressedBtf& m, ShaderDecoder& out) {
  const ShaderDecoderDescription& d = out.description;
  const int z4 = vec4sOf(m.latentDim), e4 = vec4sOf(d.modulationTerms * d.modulationChannels);
  ShaderCost& c = out.cost;
  c.textureFetches = z4 + (d.idMap ? 1 : 0);
  c.otherOps = 8 + 6;  // texel index; stereographic pair
  if (d.encoding == DirectionEncoding::StereographicHalf) c.otherOps += 3 + 6 + 3 + 3;
  const int octaves = fourierOctaves(d.encoding);
  if (octaves > 0) {
    c.transcendentals += 8;
    c.otherOps += 4 + 4 * 4 * (octaves - 1);
  }
  if (d.planeFeatures > 0 || d.clusterPlaneFeatures > 0) c.otherOps += 3 + 6 + 3;  // half vector, points
  if (d.planeFeatures > 0) addPlanesCost(d.planeFeatures, c);
  if (d.clusterPlaneFeatures > 0) addPlanesCost(d.clusterPlaneFeatures, c);
  for (const ShaderLayer& l : d.layers) {
    const double rows = 4.0 * l.groups();
    c.multiplyAdds += rows * 4 * l.inVec4s() + rows * 4;  // products, horizontal sums, biases
    (d.weightsInUniformBlocks ? c.uniformLoads : c.textureFetches) += rows * l.inVec4s() + l.groups();
    c.otherOps += rows * (l.activation == Activation::None ? 0 : l.activation == Activation::Relu ? 1 : 3);
    c.transcendentals += l.activation == Activation::Sigmoid ? rows : 0;
  }
  if (d.modulationTerms > 0) {
    c.textureFetches += e4;
    c.multiplyAdds += 3.0 * d.modulationTerms;
  }
  c.multiplyAdds += 3;  // alpha
}

void buildNeural(const CompressedBtf& m, ShaderWeights weights, ShaderDecoder& out) {
  describeNeural(m, out.name, out.description);
  placeWeights(layerGroups(m, out.name, out.description), weights, out);
  addNeuralTextures(m, out);
  out.glsl = neuralInputGlsl(m, out) + denseLayersGlsl(out) + neuralOutputGlsl(m, out.description);
  addNeuralCost(m, out);
}

// ---- The PCA baseline ---------------------------------------------------------------------

// Per image and channel: [mean, basis row]; per texel: [1, coefficients]; so one dot product
// of the two gives mean + coefficients . basis. Then the measured directions.
void addPcaTextures(const CompressedBtf& m, int row4, ShaderDecoder& out) {
  const std::string& name = out.name;
  const int C = m.latentDim, images = m.numImages();
  std::vector<float> rows(static_cast<std::size_t>(3) * images * row4 * 4, 0.0f);
  for (int r = 0; r < 3 * images; ++r) {
    float* dst = rows.data() + static_cast<std::size_t>(r) * row4 * 4;
    dst[0] = m.pcaMean[r];
    std::copy_n(m.pcaBasis.data() + static_cast<std::size_t>(r) * C, C, dst + 1);
  }
  std::vector<float> coefficients(static_cast<std::size_t>(m.numTexels()) * row4 * 4, 0.0f);
  for (int t = 0; t < m.numTexels(); ++t) {
    float* dst = coefficients.data() + static_cast<std::size_t>(t) * row4 * 4;
    dst[0] = 1;
    std::copy_n(m.latents.data() + static_cast<std::size_t>(t) * C, C, dst + 1);
  }
  std::vector<float> dirs;
  for (const auto* set : {&m.lights, &m.views})
    for (const Direction& dir : *set) {
      auto u = dir.unitVector();
      dirs.insert(dirs.end(), {static_cast<float>(u[0]), static_cast<float>(u[1]), static_cast<float>(u[2]), 0.0f});
    }
  out.textures.push_back(makeTexture(name, "nbtf_pca_rows",
                                     "PCA mean and basis per image channel ([mean, basis], " + std::to_string(row4) +
                                         " vec4 per row, row 3 x image + channel)",
                                     rows));
  out.textures.push_back(makeTexture(name, "nbtf_pca_coefficients",
                                     "PCA coefficients per texel ([1, coefficients], " + std::to_string(row4) + " vec4)",
                                     coefficients));
  out.textures.push_back(makeTexture(name, "nbtf_directions", "measured light then view unit vectors", dirs));
}

// How many measured lights, views and pairs the shader's search keeps, and how many pairs it blends.
struct PcaSearch {
  int lights, views, pairs, used;
};

PcaSearch pcaSearchOf(const ShaderDecoderDescription& d) {
  const int nl = std::min(kPcaKeep, d.lights), nv = std::min(kPcaKeep, d.views);
  const int keep = std::min(kPcaKeep, nl * nv), used = std::min(kPcaNeighbours, keep);
  return {nl, nv, keep, used};
}

// The constants, the angle between directions, and one measured image's value at a texel.
std::string pcaImageGlsl(const ShaderDecoderDescription& d, int row4) {
  std::ostringstream s;
  s << "// PCA baseline (codec/pca_model.h): the mean and basis at an unmeasured pair are the\n"
    << "// modified Shepard interpolation of the " << kPcaNeighbours
    << " nearest measured pairs, d = sqrt(angle(l, l_i)^2 + angle(v, v_i)^2).\n"
    << "const int NBTF_LIGHTS = " << d.lights << ";\nconst int NBTF_VIEWS = " << d.views << ";\n"
    << "float nbtf_angle(vec3 a, vec3 b) { return atan(length(cross(a, b)), dot(a, b)); }\n\n"
    << "vec3 nbtf_pca_image(int image, vec4 k[" << row4 << "]) {\n  vec3 v = vec3(0.0);\n"
    << "  for (int j = 0; j < " << row4 << "; ++j) {\n"
    << "    v.r += dot(nbtf_pca_rows_at((3 * image + 0) * " << row4 << " + j), k[j]);\n"
    << "    v.g += dot(nbtf_pca_rows_at((3 * image + 1) * " << row4 << " + j), k[j]);\n"
    << "    v.b += dot(nbtf_pca_rows_at((3 * image + 2) * " << row4 << " + j), k[j]);\n"
    << "  }\n  return v;\n}\n\n";
  return s.str();
}

// Inside nbtf_decode: the nearest lights and views by insertion, then the nearest pairs of them.
std::string pcaNearestPairsGlsl(const PcaSearch& p) {
  const int nl = p.lights, nv = p.views, keep = p.pairs;
  std::ostringstream s;
  s << "  // The " << nl << " nearest lights and " << nv << " nearest views (ties: lower index first)\n"
    << "  float la[" << nl << "]; int li[" << nl << "];\n"
    << "  for (int j = 0; j < " << nl << "; ++j) { la[j] = 1e30; li[j] = 0; }\n"
    << "  for (int i = 0; i < NBTF_LIGHTS; ++i) {\n"
    << "    float x = nbtf_angle(light, nbtf_directions_at(i).xyz);\n"
    << "    if (x < la[" << nl - 1 << "]) {\n      int j = " << nl - 1 << ";\n"
    << "      for (; j > 0 && la[j - 1] > x; --j) { la[j] = la[j - 1]; li[j] = li[j - 1]; }\n"
    << "      la[j] = x; li[j] = i;\n    }\n  }\n"
    << "  float va[" << nv << "]; int vi[" << nv << "];\n"
    << "  for (int j = 0; j < " << nv << "; ++j) { va[j] = 1e30; vi[j] = 0; }\n"
    << "  for (int i = 0; i < NBTF_VIEWS; ++i) {\n"
    << "    float x = nbtf_angle(view, nbtf_directions_at(NBTF_LIGHTS + i).xyz);\n"
    << "    if (x < va[" << nv - 1 << "]) {\n      int j = " << nv - 1 << ";\n"
    << "      for (; j > 0 && va[j - 1] > x; --j) { va[j] = va[j - 1]; vi[j] = vi[j - 1]; }\n"
    << "      va[j] = x; vi[j] = i;\n    }\n  }\n"
    << "  // The " << keep << " nearest pairs (ties: lower image index first)\n"
    << "  float cd[" << keep << "]; int ci[" << keep << "];\n"
    << "  for (int j = 0; j < " << keep << "; ++j) { cd[j] = 1e30; ci[j] = 0x7fffffff; }\n"
    << "  for (int a = 0; a < " << nl << "; ++a)\n    for (int b = 0; b < " << nv << "; ++b) {\n"
    << "      float x = sqrt(la[a] * la[a] + va[b] * va[b]);\n"
    << "      int img = li[a] * NBTF_VIEWS + vi[b];\n"
    << "      if (x < cd[" << keep - 1 << "] || (x == cd[" << keep - 1 << "] && img < ci[" << keep - 1 << "])) {\n"
    << "        int j = " << keep - 1 << ";\n"
    << "        for (; j > 0 && (cd[j - 1] > x || (cd[j - 1] == x && ci[j - 1] > img)); --j) { cd[j] = cd[j - 1]; ci[j] = ci[j - 1]; }\n"
    << "        cd[j] = x; ci[j] = img;\n      }\n    }\n";
  return s.str();
}

// The end of nbtf_decode: the nearest pairs' images blended by Shepard weights, x alpha.
std::string pcaBlendGlsl(const PcaSearch& p, float alpha) {
  const int keep = p.pairs, used = p.used;
  std::ostringstream s;
  s << "  vec3 rgb;\n"
    << "  // A measured pair (float32 angles: within 1e-6 rad) is its image alone.\n"
    << "  if (cd[0] < 1e-6) {\n    rgb = nbtf_pca_image(ci[0], k);\n  } else {\n"
    << "    float radius = " << (keep > kPcaNeighbours ? "cd[" + std::to_string(kPcaNeighbours) + "]" : "-1.0")
    << ";\n"
    << "    float w[" << used << "];\n    float sum = 0.0;\n"
    << "    for (int j = 0; j < " << used << "; ++j) {\n"
    << "      float x = cd[j];\n"
    << "      float q = radius < 0.0 ? 1.0 / x : max(0.0, radius - x) / (radius * x);\n"
    << "      w[j] = q * q;\n      sum += w[j];\n    }\n"
    << "    if (!(sum > 0.0)) {  // a tie on a symmetric grid: equal weights over the nearest\n"
    << "      sum = 0.0;\n"
    << "      for (int j = 0; j < " << used << "; ++j) { w[j] = cd[j] == cd[0] ? 1.0 : 0.0; sum += w[j]; }\n"
    << "    }\n"
    << "    rgb = vec3(0.0);\n"
    << "    for (int j = 0; j < " << used << "; ++j)\n"
    << "      if (w[j] > 0.0) rgb += (w[j] / sum) * nbtf_pca_image(ci[j], k);\n"
    << "  }\n"
    << "  return rgb * " << lit(alpha) << ";  // x alpha: linear RGB\n}\n";
  return s.str();
}

// Cost per pixel (see ShaderCost).
void addPcaCost(const ShaderDecoderDescription& d, int row4, const PcaSearch& p, ShaderCost& c) {
  const int nl = p.lights, nv = p.views, used = p.used;
  const double dirsTotal = d.lights + d.views;
  c.textureFetches = row4 + dirsTotal + used * 3.0 * row4;
  c.otherOps = 8 + dirsTotal * (6 + 4 + 3 + 2) + nl * nv * 5.0 + used * 6.0;
  c.transcendentals = dirsTotal;  // atan per measured direction
  c.multiplyAdds = used * 3.0 * 4 * row4 + used * 3.0 + 3;
}

void buildPca(const CompressedBtf& m, ShaderDecoder& out) {
  ShaderDecoderDescription& d = out.description;
  const std::string& name = out.name;
  const int C = m.latentDim, row4 = vec4sOf(C + 1);
  if (row4 > 64)
    throw Error(name + ": a PCA file of " + std::to_string(C) +
                " components: the shader keeps at most 255 per texel in registers");
  d.pcaComponents = C;
  d.lights = static_cast<int>(m.lights.size());
  d.views = static_cast<int>(m.views.size());
  addPcaTextures(m, row4, out);

  const PcaSearch search = pcaSearchOf(d);
  std::ostringstream s;
  s << fetchFunctions(out.textures) << "\n" << texelFunction(m.width, m.height);
  s << pcaImageGlsl(d, row4)
    << "vec3 nbtf_decode(vec2 uv, vec3 light, vec3 view) {\n"
    << "  int t = nbtf_texel(uv);\n"
    << "  vec4 k[" << row4 << "];\n"
    << "  for (int j = 0; j < " << row4 << "; ++j) k[j] = nbtf_pca_coefficients_at(t * " << row4 << " + j);\n"
    << pcaNearestPairsGlsl(search) << pcaBlendGlsl(search, m.alpha);
  out.glsl = s.str();
  addPcaCost(d, row4, search, out.cost);
}

}  // namespace

std::string shaderWeightsName(ShaderWeights w) {
  switch (w) {
    case ShaderWeights::Auto: return "auto";
    case ShaderWeights::Texture: return "texture";
    case ShaderWeights::UniformBlocks: return "uniform-blocks";
  }
  return "unknown";
}

ShaderWeights parseShaderWeights(const std::string& text) {
  for (ShaderWeights w : {ShaderWeights::Auto, ShaderWeights::Texture, ShaderWeights::UniformBlocks})
    if (text == shaderWeightsName(w)) return w;
  throw Error("unknown weight storage '" + text + "' (expected auto, texture or uniform-blocks)");
}

namespace {
void buildPcaShader(const CompressedBtf& m, ShaderWeights, ShaderDecoder& out) { buildPca(m, out); }

// The GLSL builder of each model kind (codec/methods/method.h), by its stored code.
struct ShaderBuilder {
  CodecMethod method;
  void (*build)(const CompressedBtf&, ShaderWeights, ShaderDecoder&);
};
const ShaderBuilder kShaderBuilders[] = {
    {CodecMethod::ClusteredNeural, buildNeural},
    {CodecMethod::PerTexelNeural, buildNeural},
    {CodecMethod::Pca, buildPcaShader},
};

const ShaderBuilder& shaderBuilderOf(const CompressedBtf& m, const std::string& name) {
  for (const ShaderBuilder& b : kShaderBuilders)
    if (b.method == m.method) return b;
  throw Error(name + ": method " + codecMethodName(m.method) + " has no GLSL form in this build");
}
}  // namespace

ShaderDecoder buildShaderDecoder(const CompressedBtf& material, const std::string& name, ShaderWeights weights) {
  material.validate(name);
  ShaderDecoder out;
  out.name = name;
  const ShaderBuilder& builder = shaderBuilderOf(material, name);
  const std::string method = codecMethodName(material.method);
  ShaderDecoderDescription& d = out.description;
  d.method = material.method;
  d.width = material.width;
  d.height = material.height;
  d.alpha = material.alpha;
  std::ostringstream head;
  head << "// nbtf decoder of " << std::filesystem::path(name).filename().string() << ": " << method << ", "
       << material.width << " x " << material.height << " texels; generated by nbtf export-shader.\n"
       << "// vec3 nbtf_decode(vec2 uv, vec3 light, vec3 view): linear RGB; light and view are unit\n"
       << "// vectors in the local frame (z = the normal). Bind the textures the manifest lists.\n\n";
  builder.build(material, weights, out);
  out.glsl = head.str() + out.glsl;
  return out;
}

std::string glslPrelude() {
  return "#version 300 es\nprecision highp float;\nprecision highp int;\nprecision highp sampler2D;\n";
}

std::string shaderManifestJson(const ShaderDecoder& shader) {
  using nlohmann::ordered_json;
  const ShaderDecoderDescription& d = shader.description;
  ordered_json j;
  j["format"] = "nbtf-shader";
  j["version"] = 1;
  j["source"] = std::filesystem::path(shader.name).filename().string();
  j["glsl"] = "nbtf_decoder.glsl";
  j["glsl_version"] = "300 es";
  j["function"] = "vec3 nbtf_decode(vec2 uv, vec3 light, vec3 view)";
  j["returns"] = "linear RGB (sRGB primaries), unclamped";
  ordered_json mat;
  mat["method"] = codecMethodName(d.method);
  mat["width"] = d.width;
  mat["height"] = d.height;
  mat["alpha"] = d.alpha;
  if (d.method == CodecMethod::Pca) {
    mat["pca_components"] = d.pcaComponents;
    mat["lights"] = d.lights;
    mat["views"] = d.views;
  } else {
    mat["direction_encoding"] = directionEncodingName(d.encoding);
    mat["direction_inputs"] = d.directionInputs();
    if (d.planeFeatures > 0) mat["direction_planes"] = {{"resolution", d.planeResolution}, {"features", d.planeFeatures}};
    if (d.clusterPlaneFeatures > 0)
      mat["cluster_planes"] = {{"resolution", d.clusterPlaneResolution}, {"features", d.clusterPlaneFeatures}};
    mat["latent_dim"] = d.latentDim;
    mat["latent_rows"] = d.latentRows;
    ordered_json layers = ordered_json::array();
    for (const ShaderLayer& l : d.layers) {
      const char* act = l.activation == Activation::Relu ? "relu" : l.activation == Activation::Sigmoid ? "sigmoid" : "linear";
      layers.push_back({{"in", l.in}, {"out", l.out}, {"activation", act}});
    }
    mat["layers"] = layers;
    if (d.modulationTerms > 0)
      mat["modulation"] = {{"terms", d.modulationTerms}, {"channels", d.modulationChannels}};
  }
  j["material"] = mat;
  ordered_json textures = ordered_json::array();
  for (const ShaderTexture& t : shader.textures) {
    textures.push_back({{"uniform", t.uniform},
                        {"file", t.file},
                        {"width", t.width},
                        {"height", t.height},
                        {"internal_format", "RGBA32F"},
                        {"format", "RGBA"},
                        {"type", "FLOAT"},
                        {"filter", "NEAREST"},
                        {"bytes", t.data.size() * sizeof(float)},
                        {"contents", t.contents}});
  }
  j["textures"] = textures;
  ordered_json blocks = ordered_json::array();
  for (std::size_t i = 0; i < shader.uniformBlocks.size(); ++i) {
    const ShaderUniformBlock& b = shader.uniformBlocks[i];
    blocks.push_back({{"block", b.block},
                      {"file", b.file},
                      {"layout", "std140"},
                      {"vec4s", b.vec4s},
                      {"bytes", b.data.size() * sizeof(float)},
                      {"contents", "decoder weights and biases"}});
  }
  j["weights"] = d.method == CodecMethod::Pca ? "none" : d.weightsInUniformBlocks ? "uniform-blocks" : "texture";
  j["uniform_blocks"] = blocks;
  j["cost_per_pixel"] = {{"multiply_adds", shader.cost.multiplyAdds},
                         {"texture_fetches", shader.cost.textureFetches},
                         {"uniform_loads", shader.cost.uniformLoads},
                         {"other_ops", shader.cost.otherOps},
                         {"transcendentals", shader.cost.transcendentals},
                         {"operations", shader.cost.operations()}};
  return j.dump(2) + "\n";
}

void writeShaderExport(const ShaderDecoder& shader, const std::string& dir) {
  const OutputFolderKind kind{"a shader export", "manifest.json", {}};
  writeFolderAtomic(dir, kind, [&](const std::filesystem::path& tmp) {
    writeWholeFile(tmp / "nbtf_decoder.glsl", shader.glsl.data(), shader.glsl.size());
    // Little-endian float32 (every platform this builds on); written as bytes.
    for (const ShaderTexture& t : shader.textures) writeWholeFile(tmp / t.file, t.data.data(), t.data.size() * sizeof(float));
    for (const ShaderUniformBlock& b : shader.uniformBlocks)
      writeWholeFile(tmp / b.file, b.data.data(), b.data.size() * sizeof(float));
    const std::string manifest = shaderManifestJson(shader);
    writeWholeFile(tmp / "manifest.json", manifest.data(), manifest.size());
  });
}

}  // namespace nbtf
