// Decoding a compressed material: the small API a renderer embeds (no torch anywhere
// behind it). Open a .nbtf once, then ask for RGB at (texel or texture coordinate, light
// direction, view direction), one at a time or in batches, or for whole images.
//
//   nbtf::NbtfDecoder dec = nbtf::NbtfDecoder::open("wool.nbtf");
//   nbtf::Rgb c = dec.evaluate(12, 40, {30, 60}, {45, 180});       // linear RGB
//   std::vector<float> img(3 * dec.width() * dec.height());
//   dec.decodeImage({37.5, 200}, {10, 45}, img.data());            // any angles
//
// Value spaces (eq. 5 of the paper): the decoder outputs linear RGB (sRGB primaries)
// divided by the material's alpha ("normalized"); OutputScale::Linear multiplies alpha
// back. Values are the network's own: not clamped, so they can be slightly negative where
// the network undershoots (clamp before display). See docs/decoding.md.
//
// Speed: the first layer W1 [z; l; v] + b is split into (W1_z z + b), computed once per
// latent row when the file is opened, and W1_dir [l; v], computed once per image (or per
// query), so the first layer costs an add. In the clustered mode an image needs one
// decoder evaluation per cluster (k), not per texel: decodeRows() evaluates the k rows,
// decodeImage() scatters them by the texel -> id list. The remaining layers run as small
// register-blocked matrix products (AVX-512, AVX2+FMA or portable SIMD, picked at run
// time). All methods are const and thread-safe.
//
// Per-texel modulation (format 1.2, codec/texel_modulation.h): a clustered material may have
// a decoder with R RGB terms per latent row and coefficients per texel; every texel's value
// is then sum_r e_tr x term r of its cluster (format 1.5: per channel, e_trc x term r's
// channel c). evaluate() and decodeImage() apply it;
// decodeRows() refuses such materials (their texels are not copies of rows).
//
// PCA files (the classic baseline, `nbtf compress --method pca`) are evaluated through the
// same API: per (light, view) the mean and basis rows are combined once (interpolated over
// neighbouring measured pairs when the pair was not measured, codec/pca_model.h), then each
// texel costs 3 dot products of length C.
//
// What evaluates is the model kind's evaluator (codec/methods/): this class checks every
// call's arguments, maps texels to latent rows and assembles images.
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "codec/nbtf_file.h"
#include "util/directions.h"

namespace nbtf {

enum class OutputScale {
  Linear,      // linear RGB (sRGB primaries) = decoder output x alpha
  Normalized,  // the decoder's raw output: linear RGB / alpha
};

struct Rgb {
  float r = 0, g = 0, b = 0;
};

// A query by texel: x in [0, width), y in [0, height) of the material (after the crop
// the file was made from; y = 0 is the top row).
struct TexelQuery {
  int x = 0, y = 0;
  Direction light, view;
};

// A query by texture coordinate and unit vectors, the form a renderer has at hand.
// (u, v) wrap (the texture tiles): texel x = floor(u * width) mod width, y likewise with
// v (v grows downwards, with the image rows). Directions are unit vectors in the local
// frame (z = surface normal); they are normalized here, and z < 0 is an error.
// The decoder's direction input of one (light, view) pair (directionInputCount values used).
using DirectionInput = std::array<float, kMaxDecoderDirectionInputs>;

struct UvQuery {
  float u = 0, v = 0;
  std::array<float, 3> light{0, 0, 1}, view{0, 0, 1};
};

// Instruction set of the evaluation kernels. Auto picks the best the CPU supports.
enum class DecoderIsa { Auto, Portable, Avx2, Avx512 };
std::string decoderIsaName(DecoderIsa isa);      // "portable" | "avx2+fma" | "avx512"
bool decoderIsaSupported(DecoderIsa isa);        // by this CPU and this build
DecoderIsa parseDecoderIsa(const std::string& text);  // "auto" | "portable" | "avx2" | "avx512"

struct DecoderOptions {
  DecoderIsa isa = DecoderIsa::Auto;
  // The per-row first-layer products (rows x first-layer width floats) are cached when
  // they fit in this many bytes; beyond it (huge per-texel materials) they are computed
  // per evaluation, which costs latentDim extra multiply-adds per first-layer unit.
  std::size_t maxCachedFirstLayerBytes = std::size_t(1) << 30;
};

namespace detail {
class MaterialEvaluator;
}

class NbtfDecoder {
 public:
  // Reads and validates the file (every nbtf::Error names it).
  static NbtfDecoder open(const std::string& path, const DecoderOptions& options = {});
  // From a material in memory; `name` is used in error messages.
  explicit NbtfDecoder(CompressedBtf material, const DecoderOptions& options = {},
                       const std::string& name = "compressed BTF");
  NbtfDecoder(NbtfDecoder&&) noexcept;
  NbtfDecoder& operator=(NbtfDecoder&&) noexcept;
  ~NbtfDecoder();

  // ---- The material
  const CompressedBtf& material() const { return material_; }
  const std::string& name() const { return name_; }
  int width() const { return material_.width; }
  int height() const { return material_.height; }
  int numTexels() const { return material_.numTexels(); }
  const std::vector<Direction>& lights() const { return material_.lights; }
  const std::vector<Direction>& views() const { return material_.views; }
  int numImages() const { return material_.numImages(); }
  float alpha() const { return material_.alpha; }
  bool clustered() const { return material_.method == CodecMethod::ClusteredNeural; }
  bool pca() const { return material_.isPca(); }
  // Decoder evaluations per image: k (clustered) or texels (per-texel, PCA).
  int latentRows() const { return material_.latentRows; }
  int latentRowOfTexel(int texel) const { return material_.latentRowOfTexel(texel); }
  // Per-texel modulation: R terms per latent row (1 without), the coefficients per term (1, or
  // 3 per channel), the effective coefficients (texels x R x channels, term r and channel c at
  // r x channels + c; empty without modulation).
  bool modulated() const { return !coefficients_.empty(); }
  int modulationTerms() const { return terms_; }
  int modulationChannels() const { return channels_; }
  const std::vector<float>& texelCoefficients() const { return coefficients_; }
  DecoderIsa isa() const { return isa_; }
  DirectionEncoding directionEncoding() const { return material_.directionEncoding; }
  int directionInputs() const { return material_.directionInputs(); }
  // FLOPs of one full decoder evaluation (every layer, multiply-add = 2), the unit
  // throughput figures are quoted in. The split first layer actually does less.
  // PCA: 3 dot products of length C per texel (the per-image basis combination not counted).
  double flopsPerEvaluation() const;

  // ---- Single evaluations (throw nbtf::Error on bad input; see the checks below)
  Rgb evaluate(int x, int y, const Direction& light, const Direction& view,
               OutputScale scale = OutputScale::Linear) const;
  Rgb evaluateUv(float u, float v, const Direction& light, const Direction& view,
                 OutputScale scale = OutputScale::Linear) const;
  Rgb evaluate(const UvQuery& query, OutputScale scale = OutputScale::Linear) const;

  // ---- Batches: rgb receives 3 floats per query. Every query is checked before any is
  // evaluated (the error names the query's index); evaluation runs on threadCount()
  // threads for large batches. Results equal the single evaluations bit for bit.
  void evaluate(const TexelQuery* queries, std::size_t count, float* rgb,
                OutputScale scale = OutputScale::Linear) const;
  void evaluate(const UvQuery* queries, std::size_t count, float* rgb,
                OutputScale scale = OutputScale::Linear) const;

  // ---- Whole images at any (light, view), measured or not.
  // One value per latent row: rgb receives 3 x latentRows() floats. Not for modulated
  // materials (an nbtf::Error): their texels are not copies of rows; use decodeImage.
  void decodeRows(const Direction& light, const Direction& view, float* rgb,
                  OutputScale scale = OutputScale::Linear, bool parallel = false) const;
  // An image of outWidth x outHeight texels (0 = the material's size; larger sizes tile
  // the texture, texel (x mod width, y mod height)), interleaved RGB, top row first.
  void decodeImage(const Direction& light, const Direction& view, float* rgb,
                   OutputScale scale = OutputScale::Linear, int outWidth = 0, int outHeight = 0,
                   bool parallel = false) const;

  // The decoder's R RGB terms of every latent row at (light, view), before any per-texel
  // mixing: 3 x modulationTerms() floats per row (R = 1 without modulation), normalized
  // (linear / alpha). What the compressor refits per-texel coefficients to.
  void decodeRowTerms(const Direction& light, const Direction& view, float* terms, bool parallel = false) const;
  // A modulated material's image from the terms decodeRowTerms gave at one (light, view): each
  // texel's coefficients mix its row's terms (decodeImage's second half, bit for bit; an
  // nbtf::Error for a material that is not modulated). Sizes as in decodeImage.
  void imageFromRowTerms(const float* terms, float* rgb, OutputScale scale = OutputScale::Linear, int outWidth = 0,
                         int outHeight = 0) const;

  // ---- Checks and mappings used by the above (exposed for front ends)
  void checkTexel(int x, int y) const;  // throws unless 0 <= x < width, 0 <= y < height
  int texelOfUv(float u, float v) const;  // wraps; throws on non-finite coordinates

 private:
  void build(const DecoderOptions& options);

  CompressedBtf material_;
  std::string name_;
  DecoderIsa isa_ = DecoderIsa::Portable;
  std::unique_ptr<detail::MaterialEvaluator> evaluator_;  // the model kind's (codec/methods/method.h)
  std::vector<float> coefficients_;                        // texels x terms_ x channels_ effective coefficients; empty = none
  int terms_ = 1, channels_ = 1;
};

// The decoder's direction input for a (light, view) pair of `material` (its encoding,
// util/directions.h, then its direction planes' features), exactly as training computed it;
// the first material.directionInputs() values are used.
DirectionInput decoderDirectionInput(const CompressedBtf& material, const Direction& light, const Direction& view);
// The same for unit vectors (queries by vector), into out.
void decoderDirectionInput(const CompressedBtf& material, const std::array<double, 3>& light,
                           const std::array<double, 3>& view, float* out);
// Materials with cluster planes (format 1.9): latent row `row`'s own plane features at a pair's
// plane points (directionPlanePoints), written into `input` (a decoderDirectionInput result)
// after the shared planes'. No-op without.
void addClusterPlaneFeatures(const CompressedBtf& material, int row, const float* points, float* input);
// The same at a pair of unit vectors (their points computed only with cluster planes).
void addClusterPlaneFeatures(const CompressedBtf& material, int row, const std::array<double, 3>& light,
                             const std::array<double, 3>& view, float* input);
// A query's direction vector normalized; throws when z < 0 or the vector is zero or not
// finite. `what` names the direction in messages.
std::array<double, 3> unitQueryVector(const std::array<float, 3>& dir, const std::string& what);

}  // namespace nbtf
