// The decoder as a GLSL ES 3.00 fragment-shader function (`nbtf export-shader`, `nbtf view`).
//
// A .nbtf file is first turned into a ShaderDecoder: the decoder's description (its stages
// in order: texel lookup, direction encoding, direction planes, cluster planes, dense layers, per-texel
// modulation, alpha; or the PCA baseline's interpolation) plus its data packed into RGBA32F
// textures. The GLSL is generated from the description alone, stage by stage, so a new
// model kind is a new stage here, not a rewrite of the generator. The generated function is
//
//   vec3 nbtf_decode(vec2 uv, vec3 light, vec3 view)
//
// uv: texture coordinate (wraps, v grows with the image rows, as NbtfDecoder::evaluateUv);
// light, view: unit vectors in the surface's local frame (z = the normal, z >= 0). It returns
// linear RGB (decoder output x alpha), unclamped, as the C++ decoder does. docs/shader.md.
//
// Everything here depends on the decoding library only (no torch, no image I/O).
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "codec/nbtf_file.h"

namespace nbtf {

// Limits of what the generated shader expresses. A layer wider than this would need more
// registers than a fragment shader has; a data texture must fit the size every WebGL2 /
// OpenGL ES 3.0 implementation supports (GL_MAX_TEXTURE_SIZE >= 2048).
constexpr int kMaxShaderLayerWidth = 256;
constexpr int kShaderTextureSize = 2048;

// One data texture: RGBA32F, NEAREST, read with texelFetch as a flat array of vec4
// (element i at (i mod width, i / width)).
struct ShaderTexture {
  std::string uniform;        // the sampler2D's name in the GLSL ("nbtf_weights")
  std::string file;           // its file in an export folder ("nbtf_weights.f32")
  std::string contents;       // what it holds, for the manifest
  int width = 0, height = 0;  // texels
  std::vector<float> data;    // width x height x 4 floats (zero padded)
  std::size_t vec4s = 0;      // elements used (the rest is padding)
};

// Where the dense layers' weights live. Uniform blocks are read through the constant cache
// (every pixel reads the same weight at the same step), textures through the texture units;
// Auto takes uniform blocks when the decoder fits kMaxShaderUniformBlocks of them.
enum class ShaderWeights { Auto, Texture, UniformBlocks };
std::string shaderWeightsName(ShaderWeights w);           // "auto" | "texture" | "uniform-blocks"
ShaderWeights parseShaderWeights(const std::string& text);  // throws nbtf::Error naming the choices
// Every WebGL2 / OpenGL ES 3.0 implementation supports uniform blocks of 16 KiB
// (GL_MAX_UNIFORM_BLOCK_SIZE) and 12 of them in a fragment shader (GL_MAX_FRAGMENT_UNIFORM_BLOCKS).
constexpr int kShaderUniformBlockVec4s = 1024;
constexpr int kMaxShaderUniformBlocks = 12;

// A run of a layer's groups of 4 output rows stored together: in the weights texture
// (block -1) or in uniform block `block`, from vec4 `offset` on. A group is its 4 rows of
// weights (each padded to whole vec4s, in4 vec4s per row) and then its 4 biases: 4 in4 + 1 vec4s.
struct ShaderLayerSegment {
  int firstGroup = 0, endGroup = 0;
  int block = -1;
  int offset = 0;
};

// A dense layer as the shader runs it: four output rows per step, a vec4 of inputs per read.
struct ShaderLayer {
  int in = 0, out = 0;
  Activation activation = Activation::None;
  std::vector<ShaderLayerSegment> segments;  // in group order, covering every group
  int inVec4s() const { return (in + 3) / 4; }
  int groups() const { return (out + 3) / 4; }
  int groupVec4s() const { return 4 * inVec4s() + 1; }
};

// One uniform block of weights: `layout(std140) uniform BLOCK { vec4 ARRAY[vec4s]; };`.
struct ShaderUniformBlock {
  std::string block;        // the block's name ("NbtfWeights0")
  std::string array;        // its vec4 array ("nbtf_wb0")
  std::string file;         // its file in an export folder ("NbtfWeights0.f32")
  std::vector<float> data;  // vec4s x 4 floats, std140 (a vec4 array is tightly packed)
  std::size_t vec4s = 0;
};

// The decoder's description: what the GLSL is generated from.
struct ShaderDecoderDescription {
  CodecMethod method = CodecMethod::ClusteredNeural;
  int width = 0, height = 0;  // texels
  float alpha = 1;
  // Neural methods
  bool weightsInUniformBlocks = false;
  DirectionEncoding encoding = DirectionEncoding::Stereographic;
  int encodingInputs = 0;   // fixed direction inputs (directionInputCount)
  int planeResolution = 0;  // direction planes (0 features = none)
  int planeFeatures = 0;
  int clusterPlaneResolution = 0;  // each latent row's own planes (0 features = none)
  int clusterPlaneFeatures = 0;
  int latentDim = 0;
  int latentRows = 0;
  bool idMap = false;  // clustered: texel -> latent row through nbtf_ids
  std::vector<ShaderLayer> layers;
  int modulationTerms = 0;  // 0 = none
  int modulationChannels = 1;
  // PCA baseline
  int pcaComponents = 0;
  int lights = 0, views = 0;

  int directionInputs() const { return encodingInputs + 3 * planeFeatures + 3 * clusterPlaneFeatures; }
};

// Work per pixel of one nbtf_decode call, counted from the description.
struct ShaderCost {
  double multiplyAdds = 0;    // scalar multiply-adds: dense layers (as padded to vec4), modulation, planes, PCA dots
  double textureFetches = 0;  // texelFetch calls
  double uniformLoads = 0;    // vec4 reads of the weights' uniform blocks (constant cache)
  double otherOps = 0;        // encoding and interpolation arithmetic (adds, divides, square roots...)
  double transcendentals = 0; // sin, cos, atan
  // Operations per pixel: multiply-adds + other + transcendentals (a fetch is counted apart).
  double operations() const { return multiplyAdds + otherOps + transcendentals; }
};

struct ShaderDecoder {
  std::string name;  // the source file, for messages and the manifest
  ShaderDecoderDescription description;
  std::vector<ShaderTexture> textures;
  std::vector<ShaderUniformBlock> uniformBlocks;  // the weights, when in uniform blocks
  std::string glsl;  // the library source: no #version line, no main (see glslPrelude)
  ShaderCost cost;
};

// Builds the description, the textures and the GLSL of `material`. A kind the generator
// cannot express (an unknown method, encoding or activation, a layer wider than
// kMaxShaderLayerWidth, data beyond kShaderTextureSize^2 vec4s, UniformBlocks for weights
// that need more than kMaxShaderUniformBlocks) throws nbtf::Error naming `name` and the kind.
ShaderDecoder buildShaderDecoder(const CompressedBtf& material, const std::string& name,
                                 ShaderWeights weights = ShaderWeights::Auto);

// "#version 300 es" and the precision statements a program puts before ShaderDecoder::glsl.
std::string glslPrelude();

// The JSON manifest of an export folder: the GLSL file and function, the material, and per
// texture its uniform, file, size, format and contents; per uniform block its name, file and
// size; the cost per pixel.
std::string shaderManifestJson(const ShaderDecoder& shader);

// Writes the export folder: nbtf_decoder.glsl, manifest.json and one little-endian float32
// file per texture and uniform block. Into a temporary folder beside `dir`, renamed onto `dir` at the end
// (an existing folder is replaced only then): on any error nothing is left behind.
void writeShaderExport(const ShaderDecoder& shader, const std::string& dir);

}  // namespace nbtf
