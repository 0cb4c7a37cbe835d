// Bonn UBO2014 `.btf` files: the DFMF variant (signature "!DFMF08FCR"), read and written;
// the FMF variants ("!FMF12FCER", "!FMF06FCR", "!FMF06FC") read.
//
// A DFMF file holds, per colour channel of a decorrelated colour model, a truncated SVD of
// the BTF matrix: U (one row per light/view pair) and S V^T stored as SxV (one row per
// texel). The value of channel c at (light/view pair i, texel t) is the dot product of
// U_c row i and SxV_c row t; the colour model then maps the channels back to RGB. Every
// format fact here comes from Bonn's public reader, cgbonn/btflib (matlab/@btf): the file
// and line are cited in docs/ubo2014.md.
//
// The material is never expanded here: rows are computed on demand from the factors.
// toStack() expands the texels of a crop into a half-float stack; computedStack() gives the
// same stack without storing it (every value computed from the factors when read), for
// materials too large to expand (io/btf_loader.h decides which).
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "io/btf_stack.h"
#include "util/directions.h"

namespace nbtf {

inline constexpr std::size_t kUbo2014BlockBytes = std::size_t{64} << 20;

// The signatures Bonn's reader knows (ubo_btf_signatures.m), and what nbtf does with them.
constexpr const char* kDfmfSignature = "!DFMF08FCR";
// Returns the known signature `bytes` starts with ("" if none).
std::string knownUboSignature(const std::string& bytes);

// The 151 directions of Bonn's Dome 1 (create_ubo_dome1_sampling.m): rings at theta 0, 11,
// 23.5, 30, 37.5, 45, 52.5, 60, 67.5, 75 degrees with 1, 6, 12, 12, 12, 18, 18, 24, 24, 24
// directions; phi evenly spaced, rings offset by 0, 15, 0, 15, 0, 0, 7.5, 0, 7.5, 0
// degrees. phi in [0, 360) here (Bonn wraps to (-180, 180]). The order is Bonn's.
const std::vector<Direction>& dome151();

// Colour models of a DFMF file (btf/private/undecorrelate.m).
enum class UboColorModel : std::int32_t {
  Rgb = 0, Yuv = 1, Lab = 2, Pca = 3, YCoCg = 4, Spectral = 5, SpectralLinear = 6,
  YlogUv = 9, YlogUlogVlog = 10, YlogUdivYVdivY = 11, LogRgb = 12,
};
std::string uboColorModelName(std::int32_t model);
// Whether nbtf decodes this colour model (every three-channel model but LAB and the spectral ones).
bool uboColorModelSupported(std::int32_t model);
// The epsilon Bonn's reader uses when the file does not say (undecorrelate.m).
constexpr float kUboDrrEps = 1e-5f;

// The header: the common meta data, the directions, the size and the DFMF fields.
struct Ubo2014Meta {
  std::string signature = kDfmfSignature;
  std::uint32_t metaVersion = 4;  // what Bonn's writer writes (write_meta_data.m)
  std::string measurementSetup, imageSensor, lightSource;  // at most 80 bytes each
  float ppmm = 0;
  std::array<float, 3> rgbScale{1, 1, 1};
  std::uint32_t cosineFlag = 0;  // 1: the data holds cos(theta_light) times the reflectance
  std::string xml;
  std::vector<std::string> channelNames{"R", "G", "B"};
  std::vector<Direction> lights, views;  // the file's own, in its order; degrees, phi in [0, 360)
  int width = 0, height = 0;
  std::vector<std::array<float, 9>> rotations;
  std::uint32_t maxComponents = 0;
  std::int32_t colorModel = 0;
  std::array<float, 3> colorMean{0, 0, 0};
  std::array<float, 9> colorTransform{1, 0, 0, 0, 1, 0, 0, 0, 1};  // row-major, as stored
};

// One channel's factors, as floats (half-precision files are converted on reading).
struct Ubo2014Channel {
  int scalarSize = 2;      // bytes per stored scalar: 2 (half), 4 (float) or 8 (double)
  int components = 0;
  int uRows = 0;           // rows of U (light/view pairs, or texels)
  int sxvRows = 0;         // rows of SxV (the other one)
  std::vector<float> s;    // singular values (stored, unused by decoding)
  std::vector<float> u;    // uRows x components, row-major
  std::vector<float> sxv;  // sxvRows x components, row-major
};

class Ubo2014Btf {
 public:
  Ubo2014Btf() = default;
  // Checks that the channels fit the meta data (sizes, orientation, colour model);
  // `source` names the material in errors.
  Ubo2014Btf(Ubo2014Meta meta, std::vector<Ubo2014Channel> channels, std::string source = "");

  // Reads a DFMF file, or an FMF one (one factorization of all channels: read as three
  // channels with a shared SxV, colour model 0, or 12 when its dynamic range was reduced;
  // written back as the equivalent DFMF). Throws nbtf::Error naming the file and what is wrong: another
  // signature (named, with what nbtf supports), a truncated file (which part, bytes
  // expected and left), sizes that do not fit, an unsupported colour model, trailing bytes.
  static Ubo2014Btf read(const std::string& path);
  // Writes it (atomically); scalars in each channel's scalarSize.
  void write(const std::string& path) const;

  const Ubo2014Meta& meta() const { return meta_; }
  const std::vector<Ubo2014Channel>& channels() const { return channels_; }
  const std::string& source() const { return source_; }
  int numLights() const { return static_cast<int>(meta_.lights.size()); }
  int numViews() const { return static_cast<int>(meta_.views.size()); }
  int numImages() const { return numLights() * numViews(); }
  int width() const { return meta_.width; }
  int height() const { return meta_.height; }
  int numTexels() const { return meta_.width * meta_.height; }
  // True when U's rows are light/view pairs (each texel's ABRDF is U times its SxV row,
  // "abrdfs stacked column-wise"), false when U's rows are texels.
  bool abrdfsInU() const { return abrdfsInU_; }

  // nbtf's order everywhere: image = light * numViews + view, texel = y * width + x.
  // One texel's ABRDF, linear RGB: out[3 * image + channel].
  void abrdfLinear(int texel, float* out) const;
  // Several texels at once: out[(k * numImages + image) * 3 + channel] for texels[k].
  void abrdfsLinear(const int* texels, int count, float* out) const;
  // One image, linear RGB, width * height * 3 floats.
  void imageLinear(int image, float* out) const;
  // Images [first, first + count) at the texels of `crop` (y * crop.width + x), linear RGB:
  // out[(i * crop texels + texel) * 3 + channel]. Each texel's factors are read once for all
  // the images. The same bits as valueLinear.
  void imagesLinear(int first, int count, const Crop& crop, float* out) const;
  // Texels texels[k] (of the whole material) in images[j] (nullptr: every image, j = image),
  // linear RGB: out[(3 j + c) * count + k]. The same bits as valueLinear.
  void gatherLinear(const int* images, int numImages, const int* texels, int count, float* out) const;
  // One texel in one image, linear RGB (the same arithmetic as the two above).
  void valueLinear(int image, int texel, float* rgb) const;

  // Bytes the factors take in memory (floats), and the material once expanded to float32 RGB.
  std::size_t factorBytes() const;
  std::size_t expandedFloat32Bytes() const {
    return static_cast<std::size_t>(numImages()) * numTexels() * 3 * 4;
  }

  // The texels of `crop` (empty = all) expanded into a half-float stack, the pipeline's input:
  // crop texels x images x 6 bytes. Directions in the file's order. Throws naming the file
  // when the crop lies outside the material.
  BtfStack toStack(const Crop& crop, bool progress = true) const;
  // The same stack, value for value (clamped at zero and rounded to half floats as toStack
  // stores them), computed on demand: it keeps `btf` (its factors) instead of crop texels x
  // images x 6 bytes. Slower to read: each value is three dot products of the components.
  // Whole images are made blockBytes of them at a time (see ubo2014ComputedBlockBytes).
  static BtfStack computedStack(std::shared_ptr<const Ubo2014Btf> btf, const Crop& crop,
                                std::size_t blockBytes = kUbo2014BlockBytes);
  // The crop a load applies (empty = the whole material); throws naming the file when it lies
  // outside the material.
  Crop checkedCrop(const Crop& requested) const;

 private:
  // Undecorrelates n values of one light/view pair (in place, channel by channel: r[t], g[t],
  // b[t]) into linear RGB. Every value goes through the same operations in the same order
  // whatever n is, so a tile of texels gets the bits one value alone gets.
  void toRgb(float* r, float* g, float* b, int n, int lightIndex) const;
  int fileRow(int image) const;  // nbtf image -> the file's light/view row (light fastest)
  // The values of texels texelAt(k), k < count, in images imageAt(j), j < numImages, a tile of
  // texels at a time (their factors read once for all the images): store(j, k0, n, rgb) with
  // rgb[c][t] the value of channel c at texel k0 + t, t < n.
  template <class ImageAt, class TexelAt, class Store>
  void computeValues(int numImages, ImageAt imageAt, int count, TexelAt texelAt, Store store) const;
  void setProvenance(BtfStack& stack, const Crop& crop) const;

  Ubo2014Meta meta_;
  std::vector<Ubo2014Channel> channels_;
  std::string source_;
  bool abrdfsInU_ = true;
  std::array<float, 9> rgbFromYuv_{};
};

// A computed stack (Ubo2014Btf::computedStack) makes whole images a block at a time, about
// blockBytes of floats (at least one image, at most 1/64 of them), and keeps
// ubo2014BlocksKept() blocks. At most ubo2014BlocksHeld() exist at once (those kept, and per
// thread one buffer in the making or spare for the next block and one a reader may still
// hold after it was dropped): ubo2014ComputedBlockBytes besides the factors.
int ubo2014ImagesPerBlock(int texels, int images, std::size_t blockBytes = kUbo2014BlockBytes);
int ubo2014BlocksKept();
int ubo2014BlocksHeld();
std::size_t ubo2014ComputedBlockBytes(int texels, int images, std::size_t blockBytes = kUbo2014BlockBytes);

// A path the loaders treat as a UBO2014 file: a regular file named *.btf or starting with '!'.
bool looksLikeUbo2014(const std::string& path);

}  // namespace nbtf
