#include "io/ubo2014_btf.h"

#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>
#include <set>
#include <sstream>

#include "util/atomic_file.h"
#include "util/byte_io.h"
#include "util/error.h"
#include "util/printable.h"
#include "util/half.h"
#include "util/parallel.h"
#include "util/progress.h"
#include "util/simd.h"

namespace nbtf {
namespace fs = std::filesystem;

namespace {

constexpr double kPi = 3.14159265358979323846;

// Signatures of ubo_btf_signatures.m, longest first so "!FMF06FCR" is not taken for "!FMF06FC".
struct KnownSignature {
  const char* text;
  const char* what;
};
const KnownSignature kSignatures[] = {
    {"!DFMF08FCR", "DFMF: decorrelated colour, one matrix factorization per channel (the UBO2014 format)"},
    {"!FMF12FCER", "FMF: one matrix factorization of all channels, extended header"},
    {"!BDIF06R2!", "BDI: uncompressed bidirectional images"},
    {"!FMF06FCR", "FMF: one matrix factorization of all channels"},
    {"!PVF06FCR", "PVF: per-view factorization"},
    {"!FMF06FC", "FMF: one matrix factorization of all channels"},
    {"!PVF06FC", "PVF: per-view factorization"},
};

// n scalars of `scalarSize` bytes (2: half, 4: float, 8: double) as floats, read in chunks
// (the arrays of a whole material are GB).
std::vector<float> readScalars(ByteReader& r, std::uint64_t n, int scalarSize, const std::string& what) {
  if (n > std::numeric_limits<std::uint64_t>::max() / 8) r.needItems(n, scalarSize, what);  // a hostile count
  r.need(n * scalarSize, what);
  std::vector<float> out(n);
  constexpr std::uint64_t kChunk = 1 << 20;
  for (std::uint64_t done = 0; done < n; done += kChunk) {
    const std::uint64_t m = std::min(kChunk, n - done);
    const unsigned char* chunk = r.take(m * scalarSize, what.c_str());
    for (std::uint64_t i = 0; i < m; ++i) {
      const unsigned char* p = chunk + i * scalarSize;
      if (scalarSize == 2) {
        std::uint16_t h;
        std::memcpy(&h, p, 2);
        out[done + i] = halfToFloat(h);
      } else if (scalarSize == 4) {
        std::memcpy(&out[done + i], p, 4);
      } else {
        double d;
        std::memcpy(&d, p, 8);
        out[done + i] = static_cast<float>(d);
      }
    }
  }
  return out;
}

// Stored angles are (polar, azimuth) in radians; nbtf keeps degrees with phi in [0, 360),
// rounded to 1/1000 degree so that a float32 11 degrees reads as 11.
Direction directionFromRadians(float theta, float phi) {
  auto round3 = [](double d) { return std::round(d * 1000.0) / 1000.0; };
  double t = round3(theta * 180.0 / kPi), p = round3(phi * 180.0 / kPi);
  p = std::fmod(p, 360.0);
  if (p < 0) p += 360.0;
  if (p >= 360.0) p -= 360.0;
  return {t, p};
}

std::array<float, 2> radiansFromDirection(const Direction& d) {
  double phi = std::fmod(d.phiDeg, 360.0);
  if (phi < 0) phi += 360.0;
  if (phi > 180.0) phi -= 360.0;  // Bonn's writer stores atan2's (-180, 180] (cart2sph2.m)
  return {static_cast<float>(d.thetaDeg * kPi / 180.0), static_cast<float>(phi * kPi / 180.0)};
}

// YUV -> RGB as Bonn's reader has it (undecorrelate.m), row-major.
constexpr std::array<float, 9> kRgbFromYuv{1, 0, 1.13983f, 1, -0.39465f, -0.5806f, 1, 2.03211f, 0};

class Writer {
 public:
  void bytes(const void* p, std::size_t n) {
    const auto* c = static_cast<const std::uint8_t*>(p);
    out.insert(out.end(), c, c + n);
  }
  template <class T>
  void value(T v) {
    bytes(&v, sizeof v);
  }
  void scalars(const std::vector<float>& v, int scalarSize) {
    for (float f : v) {
      if (scalarSize == 2) value(floatToHalf(f));
      else if (scalarSize == 4) value(f);
      else value(static_cast<double>(f));
    }
  }
  std::vector<std::uint8_t> out;
};

}  // namespace

std::string knownUboSignature(const std::string& bytes) {
  for (const KnownSignature& s : kSignatures)
    if (bytes.compare(0, std::strlen(s.text), s.text) == 0) return s.text;
  return "";
}

const std::vector<Direction>& dome151() {
  static const std::vector<Direction> dirs = [] {
    const double theta[] = {0, 11, 23.5, 30, 37.5, 45, 52.5, 60, 67.5, 75};
    const int count[] = {1, 6, 12, 12, 12, 18, 18, 24, 24, 24};
    const double offset[] = {0, 15, 0, 15, 0, 0, 7.5, 0, 7.5, 0};
    std::vector<Direction> d;
    for (int r = 0; r < 10; ++r)
      for (int i = 0; i < count[r]; ++i) d.push_back({theta[r], std::fmod(offset[r] + 360.0 * i / count[r], 360.0)});
    return d;
  }();
  return dirs;
}

std::string uboColorModelName(std::int32_t model) {
  switch (model) {
    case 0: return "RGB";
    case 1: return "YUV";
    case 2: return "LAB";
    case 3: return "PCA";
    case 4: return "YCoCg";
    case 5: return "spectral";
    case 6: return "spectral linear";
    case 9: return "Ylog UV";
    case 10: return "Ylog Ulog Vlog";
    case 11: return "Ylog U/Y V/Y";
    case 12: return "log RGB";
    default: return "unknown (" + std::to_string(model) + ")";
  }
}

bool uboColorModelSupported(std::int32_t m) {
  return m == 0 || m == 1 || m == 3 || m == 4 || m == 9 || m == 10 || m == 11 || m == 12;
}

bool looksLikeUbo2014(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return false;
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext == ".btf") return true;
  std::ifstream in(path, std::ios::binary);
  return in && in.get() == '!';
}

Ubo2014Btf::Ubo2014Btf(Ubo2014Meta meta, std::vector<Ubo2014Channel> channels, std::string source)
    : meta_(std::move(meta)), channels_(std::move(channels)), source_(std::move(source)), rgbFromYuv_(kRgbFromYuv) {
  const std::string& name = source_.empty() ? std::string("UBO2014 material") : source_;
  auto fail = [&](const std::string& m) { throw fileError(name, m); };
  if (meta_.lights.empty() || meta_.views.empty()) fail("no light or view directions");
  if (meta_.width <= 0 || meta_.height <= 0) fail("texture size must be positive");
  if (channels_.size() != 3)
    fail(std::to_string(channels_.size()) + " channels: nbtf reads three-channel (colour) files only");
  if (!uboColorModelSupported(meta_.colorModel))
    fail("colour model " + uboColorModelName(meta_.colorModel) + " is not supported (nbtf decodes models 0, 1, 3, 4, 9, "
         "10, 11, 12 of Bonn's undecorrelate.m)");
  const long long pairs = static_cast<long long>(numImages()), texels = numTexels();
  for (std::size_t c = 0; c < channels_.size(); ++c) {
    const Ubo2014Channel& ch = channels_[c];
    std::string which = "channel " + std::to_string(c) + ": ";
    if (ch.components < 1) fail(which + "no components");
    bool inU = ch.uRows == pairs && ch.sxvRows == texels;
    bool inSxV = ch.uRows == texels && ch.sxvRows == pairs;
    if (!inU && !inSxV) {
      std::ostringstream s;
      s << which << "U has " << ch.uRows << " rows and SxV " << ch.sxvRows << "; expected " << pairs
        << " (lights x views = " << numLights() << " x " << numViews() << ") and " << texels << " (texels = "
        << width() << " x " << height() << "), in either order";
      fail(s.str());
    }
    if (c == 0) abrdfsInU_ = inU;
    else if (abrdfsInU_ != inU && !(inU && inSxV)) fail(which + "U and SxV are swapped with respect to channel 0");
    if (ch.u.size() != static_cast<std::size_t>(ch.uRows) * ch.components ||
        ch.sxv.size() != static_cast<std::size_t>(ch.sxvRows) * ch.components)
      fail(which + "factor sizes do not match rows x components");
  }
}

int Ubo2014Btf::fileRow(int image) const {
  const int light = image / numViews(), view = image % numViews();
  return light + numLights() * view;
}

void Ubo2014Btf::toRgb(float* __restrict r, float* __restrict g, float* __restrict b, int n, int lightIndex) const {
  // One loop per step, with the switch outside: the arithmetic loops vectorize, the exp ones
  // call the library's expf value by value (a vector exp would round differently).
  const float eps = kUboDrrEps;
  auto expMinusEps = [&](float* x) {
    for (int t = 0; t < n; ++t) x[t] = std::exp(x[t]) - eps;
  };
  auto yuv = [&] {
    const auto& m = rgbFromYuv_;
    for (int t = 0; t < n; ++t) {
      const float y = r[t], u = g[t], w = b[t];
      r[t] = m[0] * y + m[1] * u + m[2] * w;
      g[t] = m[3] * y + m[4] * u + m[5] * w;
      b[t] = m[6] * y + m[7] * u + m[8] * w;
    }
  };
  switch (meta_.colorModel) {
    case 0: break;
    case 1: yuv(); break;
    case 3: {
      const auto& tr = meta_.colorTransform;
      const auto& mean = meta_.colorMean;
      for (int t = 0; t < n; ++t) {
        const float x = r[t], y = g[t], z = b[t];
        r[t] = x * tr[0] + y * tr[3] + z * tr[6] + mean[0];
        g[t] = x * tr[1] + y * tr[4] + z * tr[7] + mean[1];
        b[t] = x * tr[2] + y * tr[5] + z * tr[8] + mean[2];
      }
      break;
    }
    case 4:
      for (int t = 0; t < n; ++t) {
        const float y = r[t], co = g[t], cg = b[t];
        r[t] = y + co - cg, g[t] = y + cg, b[t] = y - co - cg;
      }
      break;
    case 9: expMinusEps(r); yuv(); break;
    case 10: {
      expMinusEps(r);
      const float logEps = std::log(eps);
      for (float* c : {g, b})
        for (int t = 0; t < n; ++t) c[t] = (c[t] > 0 ? 1.f : c[t] < 0 ? -1.f : 0.f) * std::exp(std::abs(c[t]) + logEps);
      yuv();
      break;
    }
    case 11:
      expMinusEps(r);
      for (int t = 0; t < n; ++t) {
        const float scale = r[t] + eps;
        g[t] *= scale, b[t] *= scale;
      }
      yuv();
      break;
    case 12:
      for (float* c : {r, g, b}) expMinusEps(c);
      break;
  }
  if (meta_.cosineFlag) {
    const float cosTheta = static_cast<float>(std::cos(meta_.lights[lightIndex].thetaDeg * kPi / 180.0));
    for (float* c : {r, g, b})
      for (int t = 0; t < n; ++t) c[t] /= cosTheta;
  }
}

namespace {
// Eight independent partial sums (a fixed order, so the same bits everywhere): the compiler
// vectorizes them, where one running sum waits on every addition. valueLinear calls it three
// times per value; dotsK gives the same bits for a tile of texels.
float dotK(const float* a, const float* b, int k) {
  float lane[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  int j = 0;
  for (; j + 8 <= k; j += 8)
    for (int l = 0; l < 8; ++l) lane[l] += a[j + l] * b[j + l];
  for (int l = 0; j < k; ++j, ++l) lane[l] += a[j] * b[j];
  return ((lane[0] + lane[4]) + (lane[1] + lane[5])) + ((lane[2] + lane[6]) + (lane[3] + lane[7]));
}

// Texel t of a crop (y * crop.width + x) in a material `width` texels wide.
int materialTexel(const Crop& crop, int width, int t) {
  return (crop.y + t / crop.width) * width + crop.x + t % crop.width;
}

constexpr int kTile = 64;  // texels whose factors computeValues keeps at hand

// dotK(a, b_t) for the texels t0 .. t0 + lanes(V) - 1 of a tile, whose factors tileT holds
// component-major (b_t[j] = tileT[j * kTile + t]): the same eight partial sums, added in the
// same order, so the same bits as dotK, but one vector V of texels at a time, its eight
// partial sums in registers.
template <class V>
inline void dotsGroup(const float* a, const float* tileT, int k, int t0, float* out) {
  V lane[8] = {};
  auto add = [&](int l, int j) {
    V b;
    std::memcpy(&b, tileT + static_cast<std::size_t>(j) * kTile + t0, sizeof(V));
    lane[l] += a[j] * b;
  };
  int j = 0;
  for (; j + 8 <= k; j += 8) {
#pragma GCC unroll 8
    for (int l = 0; l < 8; ++l) add(l, j + l);
  }
#pragma GCC unroll 8
  for (int l = 0; l < 8; ++l)
    if (j + l < k) add(l, j + l);
  const V sum = ((lane[0] + lane[4]) + (lane[1] + lane[5])) + ((lane[2] + lane[6]) + (lane[3] + lane[7]));
  std::memcpy(out + t0, &sum, sizeof(V));
}

typedef float Floats4 __attribute__((vector_size(16)));
typedef float Floats8 __attribute__((vector_size(32)));

// dotsGroup over the texels t < n of a tile (whole groups: out holds kTile floats).
void dotsK4(const float* a, const float* tileT, int k, int n, float* out) {
  for (int t0 = 0; t0 < n; t0 += 4) dotsGroup<Floats4>(a, tileT, k, t0, out);
}
NBTF_AVX void dotsK8(const float* a, const float* tileT, int k, int n, float* out) {
  for (int t0 = 0; t0 < n; t0 += 8) dotsGroup<Floats8>(a, tileT, k, t0, out);
}
void dotsK(const float* a, const float* tileT, int k, int n, float* out) {
  static const bool wide = hasAvx();
  (wide ? dotsK8 : dotsK4)(a, tileT, k, n, out);
}
}  // namespace

void Ubo2014Btf::abrdfLinear(int texel, float* out) const { abrdfsLinear(&texel, 1, out); }

void Ubo2014Btf::imageLinear(int image, float* out) const { imagesLinear(image, 1, Crop{0, 0, width(), height()}, out); }

template <class ImageAt, class TexelAt, class Store>
void Ubo2014Btf::computeValues(int numImages, ImageAt imageAt, int count, TexelAt texelAt, Store store) const {
  const float* angular[3];
  const float* spatial[3];
  int k[3];
  for (int c = 0; c < 3; ++c) {
    const Ubo2014Channel& ch = channels_[c];
    angular[c] = abrdfsInU_ ? ch.u.data() : ch.sxv.data();
    spatial[c] = abrdfsInU_ ? ch.sxv.data() : ch.u.data();
    k[c] = ch.components;
  }
  std::vector<float> tiles[3];
  for (int c = 0; c < 3; ++c) tiles[c].resize(static_cast<std::size_t>(k[c]) * kTile);
  float v[3][kTile];
  for (int t0 = 0; t0 < count; t0 += kTile) {
    const int n = std::min(kTile, count - t0);
    for (int t = 0; t < n; ++t) {
      const std::size_t texel = static_cast<std::size_t>(texelAt(t0 + t));
      for (int c = 0; c < 3; ++c)
        for (int j = 0; j < k[c]; ++j) tiles[c][static_cast<std::size_t>(j) * kTile + t] = spatial[c][texel * k[c] + j];
    }
    for (int i = 0; i < numImages; ++i) {
      const int image = imageAt(i);
      const std::size_t row = static_cast<std::size_t>(fileRow(image));
      for (int c = 0; c < 3; ++c) dotsK(angular[c] + row * k[c], tiles[c].data(), k[c], n, v[c]);
      toRgb(v[0], v[1], v[2], n, image / numViews());
      store(i, t0, n, v);
    }
  }
}

void Ubo2014Btf::imagesLinear(int first, int count, const Crop& crop, float* out) const {
  const int texels = crop.width * crop.height;
  computeValues(
      count, [&](int i) { return first + i; }, texels,
      [&](int t) { return materialTexel(crop, width(), t); },
      [&](int i, int t0, int n, const float (*rgb)[kTile]) {
        float* o = out + (static_cast<std::size_t>(i) * texels + t0) * 3;
        for (int t = 0; t < n; ++t) o[3 * t] = rgb[0][t], o[3 * t + 1] = rgb[1][t], o[3 * t + 2] = rgb[2][t];
      });
}

void Ubo2014Btf::gatherLinear(const int* images, int numImages, const int* texels, int count, float* out) const {
  if (!images) numImages = this->numImages();
  computeValues(
      numImages, [&](int j) { return images ? images[j] : j; }, count, [&](int t) { return texels[t]; },
      [&](int j, int t0, int n, const float (*rgb)[kTile]) {
        for (int c = 0; c < 3; ++c) std::copy_n(rgb[c], n, out + static_cast<std::size_t>(3 * j + c) * count + t0);
      });
}

void Ubo2014Btf::abrdfsLinear(const int* texels, int count, float* out) const {
  const int pairs = numImages();
  computeValues(
      pairs, [](int image) { return image; }, count, [&](int k) { return texels[k]; },
      [&](int image, int k0, int n, const float (*rgb)[kTile]) {
        for (int t = 0; t < n; ++t) {
          float* o = out + (static_cast<std::size_t>(k0 + t) * pairs + image) * 3;
          o[0] = rgb[0][t], o[1] = rgb[1][t], o[2] = rgb[2][t];
        }
      });
}

void Ubo2014Btf::valueLinear(int image, int texel, float* rgb) const {
  const std::size_t row = static_cast<std::size_t>(fileRow(image));
  for (int c = 0; c < 3; ++c) {
    const Ubo2014Channel& ch = channels_[c];
    const float* angular = (abrdfsInU_ ? ch.u.data() : ch.sxv.data()) + row * ch.components;
    const float* spatial = (abrdfsInU_ ? ch.sxv.data() : ch.u.data()) + static_cast<std::size_t>(texel) * ch.components;
    rgb[c] = dotK(angular, spatial, ch.components);
  }
  toRgb(rgb, rgb + 1, rgb + 2, 1, image / numViews());
}

std::size_t Ubo2014Btf::factorBytes() const {
  std::size_t n = 0;
  for (const Ubo2014Channel& ch : channels_) n += (ch.u.size() + ch.sxv.size() + ch.s.size()) * sizeof(float);
  return n;
}

Crop Ubo2014Btf::checkedCrop(const Crop& requested) const {
  Crop crop = requested.empty() ? Crop{0, 0, width(), height()} : requested;
  if (crop.x < 0 || crop.y < 0 || crop.width < 1 || crop.height < 1 || crop.x + crop.width > width() ||
      crop.y + crop.height > height()) {
    std::ostringstream s;
    s << "crop " << crop.x << "," << crop.y << "," << crop.width << "," << crop.height << " lies outside the "
      << width() << " x " << height() << " material";
    throw fileError(source_, s.str());
  }
  return crop;
}

void Ubo2014Btf::setProvenance(BtfStack& stack, const Crop& crop) const {
  stack.source = source_;
  stack.layout = Layout::Ubo2014;
  stack.sourceWidth = width();
  stack.sourceHeight = height();
  stack.crop = crop;
}

namespace {

// A crop of a factorized material, its values computed on demand (BtfStack::isComputed).
//
// Whole images are made a block of consecutive images at a time (imagesLinear), so that each
// texel's factors are read from memory once per block, not once per image; a few blocks are
// kept. A thread that finds its block being made by another one makes a block after it
// meanwhile: the passes read images in order from several threads, and all of them stay busy.
class FactorizedValues : public ComputedStackValues {
 public:
  FactorizedValues(std::shared_ptr<const Ubo2014Btf> btf, Crop crop, std::size_t blockBytes)
      : btf_(std::move(btf)),
        crop_(crop),
        blockBytes_(blockBytes),
        imagesPerBlock_(ubo2014ImagesPerBlock(crop.width * crop.height, btf_->numImages(), blockBytes)),
        blocks_((btf_->numImages() + imagesPerBlock_ - 1) / imagesPerBlock_),
        capacity_(ubo2014BlocksKept()) {}
  void image(int image, float* out) const override {
    const std::size_t values = static_cast<std::size_t>(crop_.width) * crop_.height * 3;
    std::shared_ptr<const Block> b = block(image / imagesPerBlock_);
    std::copy_n(b->rgb.data() + static_cast<std::size_t>(image % imagesPerBlock_) * values, values, out);
  }
  void value(int image, int texel, float rgb[3]) const override {
    btf_->valueLinear(image, fileTexel(texel), rgb);
    roundToHalfClampedAtZero(rgb, 3);
  }
  void gather(const int* images, int numImages, const int* texels, int count, float* out) const override {
    const int cropTexels = crop_.width * crop_.height;
    if (images && numImages == 1 && count * 16 >= cropTexels) {  // much of one image: its block
      std::shared_ptr<const Block> b = block(images[0] / imagesPerBlock_);
      const float* rgb = b->rgb.data() + static_cast<std::size_t>(images[0] % imagesPerBlock_) * cropTexels * 3;
      for (int k = 0; k < count; ++k)
        for (int c = 0; c < 3; ++c) out[static_cast<std::size_t>(c) * count + k] = rgb[3 * static_cast<std::size_t>(texels[k]) + c];
      return;
    }
    std::vector<int> file(count);
    for (int k = 0; k < count; ++k) file[k] = fileTexel(texels[k]);
    btf_->gatherLinear(images, numImages, file.data(), count, out);
    roundToHalfClampedAtZero(out, static_cast<std::size_t>(images ? numImages : btf_->numImages()) * 3 * count);
  }
  std::size_t bytes() const override {
    return btf_->factorBytes() + ubo2014ComputedBlockBytes(crop_.width * crop_.height, btf_->numImages(), blockBytes_);
  }

 private:
  struct Block {
    int index = 0;
    std::vector<float> rgb;  // its images, one after the other, as image() gives them
  };

  std::shared_ptr<const Block> cached(int index) const {
    for (const auto& b : cache_)
      if (b->index == index) return b;
    return nullptr;
  }
  std::shared_ptr<const Block> block(int index) const {
    std::unique_lock<std::mutex> lock(mutex_);
    for (;;) {
      if (auto b = cached(index)) return b;
      if (!making_.count(index)) break;
      bool helped = false;
      for (int next = index + 1; next < blocks_ && next <= index + capacity_ - 2 && !helped; ++next)
        if (!cached(next) && !making_.count(next)) make(next, lock), helped = true;
      if (!helped) made_.wait(lock);
    }
    make(index, lock);
    return cached(index);
  }
  // Makes block `index` with the lock released, then keeps it (dropping the oldest).
  void make(int index, std::unique_lock<std::mutex>& lock) const {
    making_.insert(index);
    auto b = std::make_shared<Block>();
    if (!spare_.empty()) b->rgb = std::move(spare_.back()), spare_.pop_back();
    lock.unlock();
    try {
      b->index = index;
      const int first = index * imagesPerBlock_;
      const int count = std::min(imagesPerBlock_, btf_->numImages() - first);
      b->rgb.resize(static_cast<std::size_t>(count) * crop_.width * crop_.height * 3);
      btf_->imagesLinear(first, count, crop_, b->rgb.data());
      roundToHalfClampedAtZero(b->rgb.data(), b->rgb.size());
    } catch (...) {
      lock.lock();
      making_.erase(index);
      made_.notify_all();
      throw;
    }
    lock.lock();
    making_.erase(index);
    cache_.push_back(std::move(b));
    if (static_cast<int>(cache_.size()) > capacity_) {
      // Its buffer serves a later block unless a reader still holds it: a fresh 64 MB buffer
      // costs more to zero and fault in than its values cost to compute. One spare per thread,
      // as every thread may be making a block at once.
      if (cache_.front().use_count() == 1 && static_cast<int>(spare_.size()) < threadCount())
        spare_.push_back(std::move(cache_.front()->rgb));
      cache_.pop_front();
    }
    made_.notify_all();
  }
  int fileTexel(int t) const { return materialTexel(crop_, btf_->width(), t); }

  std::shared_ptr<const Ubo2014Btf> btf_;
  Crop crop_;
  std::size_t blockBytes_;
  int imagesPerBlock_, blocks_, capacity_;
  mutable std::mutex mutex_;
  mutable std::condition_variable made_;
  mutable std::deque<std::shared_ptr<Block>> cache_;
  mutable std::set<int> making_;
  mutable std::vector<std::vector<float>> spare_;  // dropped blocks' buffers, at most one per thread
};

}  // namespace

int ubo2014ImagesPerBlock(int texels, int images, std::size_t blockBytes) {
  const std::size_t bytesPerImage = static_cast<std::size_t>(std::max(1, texels)) * 3 * sizeof(float);
  // at most 1/64 of the images: the blocks kept stay small beside a small material's factors
  const std::size_t most = std::max(1, (images + 63) / 64);
  return static_cast<int>(std::clamp<std::size_t>(blockBytes / bytesPerImage, 1, most));
}
int ubo2014BlocksKept() { return threadCount() + 2; }
int ubo2014BlocksHeld() { return ubo2014BlocksKept() + 2 * threadCount(); }
std::size_t ubo2014ComputedBlockBytes(int texels, int images, std::size_t blockBytes) {
  return static_cast<std::size_t>(ubo2014BlocksHeld()) * ubo2014ImagesPerBlock(texels, images, blockBytes) * texels * 3 *
         sizeof(float);
}

BtfStack Ubo2014Btf::computedStack(std::shared_ptr<const Ubo2014Btf> btf, const Crop& requested,
                                   std::size_t blockBytes) {
  const Crop crop = btf->checkedCrop(requested);
  const Ubo2014Btf& b = *btf;
  BtfStack stack(b.meta_.lights, b.meta_.views, crop.width, crop.height, SampleType::Half,
                 std::make_shared<FactorizedValues>(btf, crop, blockBytes));
  b.setProvenance(stack, requested.empty() ? Crop{} : crop);
  return stack;
}

BtfStack Ubo2014Btf::toStack(const Crop& requested, bool progress) const {
  const Crop crop = checkedCrop(requested);
  BtfStack stack(meta_.lights, meta_.views, crop.width, crop.height, SampleType::Half);
  setProvenance(stack, requested.empty() ? Crop{} : crop);

  const int texels = crop.width * crop.height, pairs = numImages();
  constexpr int kBlock = 32;
  const std::size_t blocks = (static_cast<std::size_t>(texels) + kBlock - 1) / kBlock;
  Progress bar("expand", blocks, progress);
  parallelForDynamic(blocks, [&](std::size_t b, int) {
    const int first = static_cast<int>(b) * kBlock, count = std::min(kBlock, texels - first);
    int fileTexels[kBlock];
    for (int k = 0; k < count; ++k) fileTexels[k] = materialTexel(crop, width(), first + k);
    std::vector<float> rows(static_cast<std::size_t>(count) * pairs * 3);
    abrdfsLinear(fileTexels, count, rows.data());
    for (int k = 0; k < count; ++k)
      for (int image = 0; image < pairs; ++image) {
        std::uint8_t* dst = stack.imageBytes(image) + static_cast<std::size_t>(first + k) * 6;
        for (int c = 0; c < 3; ++c) {
          // The pipeline's inputs are reflectances: a truncated SVD can dip below zero.
          std::uint16_t h = floatToHalf(std::max(0.0f, rows[(static_cast<std::size_t>(k) * pairs + image) * 3 + c]));
          std::memcpy(dst + 2 * c, &h, 2);
        }
      }
    bar.advance();
  });
  bar.finish();
  return stack;
}

namespace {

// FMF (read_ubo_fmf.m): one factorization of all channels; U's rows are channel fastest, then
// light, then view (or channel, then texel), SxV is shared. Presented as three DFMF channels
// (U split by channel, SxV copied) in RGB, or log RGB when the dynamic range was reduced.
Ubo2014Btf readFmfBody(ByteReader& r, Ubo2014Meta m, std::uint64_t pairs, std::uint64_t texels, const std::string& path) {
  std::uint8_t headerVersion = 0;
  if (m.signature == "!FMF12FCER") headerVersion = r.value<std::uint8_t>("the FMF header version");
  if (headerVersion >= 3) throw r.fail("unknown FMF header version " + std::to_string(headerVersion));
  std::uint32_t drr = 0;
  if (headerVersion >= 1) drr = r.value<std::uint32_t>("the dynamic range reduction method");
  if (headerVersion >= 2) {  // a height map (half floats); nbtf does not use it
    std::uint32_t rows = r.value<std::uint32_t>("the height map size"), cols = r.value<std::uint32_t>("the height map size");
    std::uint64_t bytes = 2ull * rows * cols;
    r.need(bytes, "the height map");
    r.text(bytes, "the height map");
  }
  m.maxComponents = r.value<std::uint32_t>("the component count");
  const int scalarSize = r.value<std::uint8_t>("the scalar size");
  if (scalarSize != 2 && scalarSize != 4 && scalarSize != 8)
    throw r.fail("unknown scalar size " + std::to_string(scalarSize) + " (2, 4 or 8 bytes)");
  const std::uint32_t k = r.value<std::uint32_t>("the component count");
  const std::uint32_t rows = r.value<std::uint32_t>("the row count"), cols = r.value<std::uint32_t>("the column count");
  const bool inU = rows == 3 * pairs && cols == texels, inSxV = rows == 3 * texels && cols == pairs;
  if (!inU && !inSxV) {
    std::ostringstream s;
    s << "the matrix is " << rows << " x " << cols << ", expected 3 x " << pairs << " (channels x lights x views) by "
      << texels << " (texels), or 3 x " << texels << " by " << pairs;
    throw r.fail(s.str());
  }
  if (k == 0 || k > std::min(rows, cols))
    throw r.fail(std::to_string(k) + " components for a " + std::to_string(rows) + " x " + std::to_string(cols) + " matrix");
  std::vector<float> sv = readScalars(r, k, scalarSize, "the singular values");
  std::vector<float> u = readScalars(r, static_cast<std::uint64_t>(rows) * k, scalarSize, "U");
  std::vector<float> sxv = readScalars(r, static_cast<std::uint64_t>(cols) * k, scalarSize, "SxV");
  for (float f : sv)
    if (!std::isfinite(f)) throw r.fail("a singular value is not finite (NaN or infinity)");
  for (const std::vector<float>* part : {&u, &sxv})
    for (float f : *part)
      if (!std::isfinite(f)) throw r.fail("a factor is not finite (NaN or infinity)");
  if (r.remaining() != 0) throw r.fail(std::to_string(r.remaining()) + " unexpected bytes after SxV (an FMF file ends there)");
  m.colorModel = drr ? 12 : 0;  // restore_dynamic_range.m: exp(x) - eps, which is colour model 12
  std::vector<Ubo2014Channel> channels(3);
  const std::size_t perChannel = rows / 3;
  for (int c = 0; c < 3; ++c) {
    Ubo2014Channel& ch = channels[c];
    ch.scalarSize = scalarSize;
    ch.components = static_cast<int>(k);
    ch.uRows = static_cast<int>(perChannel), ch.sxvRows = static_cast<int>(cols);
    ch.s = sv;
    ch.u.resize(perChannel * k);
    for (std::size_t row = 0; row < perChannel; ++row)
      std::copy_n(u.data() + (3 * row + c) * k, k, ch.u.data() + row * k);
    ch.sxv = sxv;
  }
  return Ubo2014Btf(std::move(m), std::move(channels), path);
}

}  // namespace

// One piece: a sequential parse in the order of Bonn's reader (docs/ubo2014.md cites it field by
// field), so that each check sits where that reader reads the field.
Ubo2014Btf Ubo2014Btf::read(const std::string& path) {
  ByteReader r = ByteReader::openFile(path, "UBO BTF file");
  // Signature (ubo_btf_signatures.m; read_ubo_dfmf.m seeks past it).
  std::string head = r.text(std::min<std::uint64_t>(10, r.remaining()), "the signature");
  const std::string known = knownUboSignature(head);
  if (known.empty())
    throw fileError(path, "not a UBO BTF file: it starts with '" + printableBytes(head.data(), head.size()) + "', expected the signature '" +
                              kDfmfSignature + "' (Bonn's UBO2014 format)");
  const bool fmf = known.rfind("!FMF", 0) == 0;
  if (known != kDfmfSignature && !fmf) {
    std::string what;
    for (const KnownSignature& s : kSignatures)
      if (known == s.text) what = s.what;
    throw fileError(path, "signature '" + known + "' (" + what + ") is a UBO BTF format nbtf does not read; nbtf reads '" +
                              kDfmfSignature + "' (the UBO2014 distribution format) and the FMF signatures");
  }
  Ubo2014Meta m;
  m.signature = known;
  r.seek(known.size());  // the header follows the signature (read_ubo_dfmf.m, read_ubo_fmf.m: fseek past it)

  // Meta data (read_meta_data.m): its size counts the size field itself.
  const std::uint64_t metaStart = r.position();
  const std::uint32_t metaSize = r.value<std::uint32_t>("the meta data size");
  m.metaVersion = r.value<std::uint32_t>("the meta data version");
  // Versions 1 to 4 are known (read_meta_data.m); a later one may add fields this reader
  // would take for directions.
  if (m.metaVersion < 1 || m.metaVersion > 4)
    throw r.fail("unknown meta data version " + std::to_string(m.metaVersion) + " (nbtf reads versions 1 to 4)");
  auto fixed = [&](const char* what) {
    std::string s = r.text(80, what);
    return s.substr(0, s.find('\0'));
  };
  m.measurementSetup = fixed("the measurement setup name");
  m.imageSensor = fixed("the image sensor name");
  m.lightSource = fixed("the light source name");
  m.ppmm = r.value<float>("ppmm");
  for (float& f : m.rgbScale) f = r.value<float>("the RGB scale factor");
  if (m.metaVersion > 1) m.cosineFlag = r.value<std::uint32_t>("the cosine flag");
  if (m.metaVersion > 2) {
    std::uint32_t n = r.value<std::uint32_t>("the XML length");
    m.xml = r.text(n, "the XML string");
  }
  if (m.metaVersion > 3) {
    std::uint32_t channels = r.value<std::uint32_t>("the channel count");
    if (channels != 3)
      throw r.fail(std::to_string(channels) + " channels: nbtf reads three-channel (colour) files only");
    m.channelNames.clear();
    for (std::uint32_t c = 0; c < channels; ++c) {
      std::uint32_t n = r.value<std::uint32_t>("a channel name length");
      m.channelNames.push_back(r.text(n, "a channel name"));
    }
  }
  if (r.position() - metaStart != metaSize) {
    std::ostringstream s;
    s << "meta data block says " << metaSize << " bytes, but its fields (version " << m.metaVersion << ") take "
      << r.position() - metaStart;
    throw r.fail(s.str());
  }

  // Directions (read_bidir_sampling.m): per view its (polar, azimuth) and the light list.
  const std::uint32_t views = r.value<std::uint32_t>("the view count");
  if (views == 0 || views > 100000) throw r.fail("implausible view count " + std::to_string(views));
  std::uint32_t lights = 0;
  for (std::uint32_t v = 0; v < views; ++v) {
    float theta = r.value<float>("a view direction"), phi = r.value<float>("a view direction");
    m.views.push_back(directionFromRadians(theta, phi));
    std::uint32_t n = r.value<std::uint32_t>("a light count");
    if (v == 0) {
      if (n == 0 || n > 100000) throw r.fail("implausible light count " + std::to_string(n));
      lights = n;
      for (std::uint32_t l = 0; l < n; ++l) {
        float lt = r.value<float>("a light direction"), lp = r.value<float>("a light direction");
        m.lights.push_back(directionFromRadians(lt, lp));
      }
    } else {
      if (n != lights)
        throw r.fail("view " + std::to_string(v) + " has " + std::to_string(n) + " lights, view 0 has " +
               std::to_string(lights) + " (the light set must be the same for every view)");
      r.need(8ull * n, "a view's light directions");
      r.text(8ull * n, "a view's light directions");
    }
  }
  if (static_cast<std::uint64_t>(lights) * views > (1u << 26))
    throw r.fail("implausible direction counts: " + std::to_string(lights) + " lights x " + std::to_string(views) + " views");
  for (const Direction& d : m.lights) checkHemisphere(d, path + ": light");
  for (const Direction& d : m.views) checkHemisphere(d, path + ": view");

  // Size and rotations (read_common_header.m): rotations only when the signature ends in 'R'.
  const std::uint32_t w = r.value<std::uint32_t>("the width"), h = r.value<std::uint32_t>("the height");
  if (w == 0 || h == 0 || w > 65536 || h > 65536 || static_cast<std::uint64_t>(w) * h > (1u << 30))
    throw r.fail("implausible texture size " + std::to_string(w) + " x " + std::to_string(h));
  m.width = static_cast<int>(w), m.height = static_cast<int>(h);
  if (known.back() == 'R') {
    std::uint32_t n = r.value<std::uint32_t>("the rotation count");
    r.need(36ull * n, "the rotations");
    for (std::uint32_t i = 0; i < n; ++i) {
      std::array<float, 9> rot;
      for (float& f : rot) f = r.value<float>("a rotation");
      m.rotations.push_back(rot);
    }
  }

  const std::uint64_t pairs = static_cast<std::uint64_t>(lights) * views, texels = static_cast<std::uint64_t>(w) * h;
  if (fmf) return readFmfBody(r, std::move(m), pairs, texels, path);

  // DFMF fields (read_ubo_dfmf.m).
  m.maxComponents = r.value<std::uint32_t>("the component count");
  m.colorModel = r.value<std::int32_t>("the colour model");
  for (float& f : m.colorMean) f = r.value<float>("the colour mean");
  for (float& f : m.colorTransform) f = r.value<float>("the colour transformation matrix");

  std::vector<Ubo2014Channel> channels(3);
  for (int c = 0; c < 3; ++c) {
    Ubo2014Channel& ch = channels[c];
    const std::string which = "channel " + std::to_string(c);
    ch.scalarSize = r.value<std::uint8_t>(which + "'s scalar size");
    if (ch.scalarSize != 2 && ch.scalarSize != 4 && ch.scalarSize != 8)
      throw r.fail(which + ": unknown scalar size " + std::to_string(ch.scalarSize) + " (2, 4 or 8 bytes)");
    const std::uint32_t k = r.value<std::uint32_t>(which + "'s component count");
    const std::uint32_t rows = r.value<std::uint32_t>(which + "'s row count");
    const std::uint32_t cols = r.value<std::uint32_t>(which + "'s column count");
    if (!((rows == pairs && cols == texels) || (rows == texels && cols == pairs))) {
      std::ostringstream s;
      s << which << ": the matrix is " << rows << " x " << cols << ", expected " << pairs << " (lights x views = "
        << lights << " x " << views << ") by " << texels << " (texels = " << w << " x " << h << ") in either order";
      throw r.fail(s.str());
    }
    if (k == 0 || k > std::min(rows, cols)) throw r.fail(which + ": " + std::to_string(k) + " components for a " +
                                                   std::to_string(rows) + " x " + std::to_string(cols) + " matrix");
    ch.components = static_cast<int>(k);
    ch.uRows = static_cast<int>(rows), ch.sxvRows = static_cast<int>(cols);
    ch.s = readScalars(r, k, ch.scalarSize, which + "'s singular values");
    ch.u = readScalars(r, static_cast<std::uint64_t>(rows) * k, ch.scalarSize, which + "'s U");
    ch.sxv = readScalars(r, static_cast<std::uint64_t>(cols) * k, ch.scalarSize, which + "'s SxV");
    for (float f : ch.s)
      if (!std::isfinite(f)) throw r.fail(which + ": a singular value is not finite (NaN or infinity)");
    for (const std::vector<float>* part : {&ch.u, &ch.sxv})
      for (float f : *part)
        if (!std::isfinite(f)) throw r.fail(which + ": a factor is not finite (NaN or infinity)");
  }
  if (r.remaining() != 0)
    throw r.fail(std::to_string(r.remaining()) + " unexpected bytes after the last channel (a DFMF file ends there)");
  return Ubo2014Btf(std::move(m), std::move(channels), path);
}

void Ubo2014Btf::write(const std::string& path) const {
  Writer w;
  const Ubo2014Meta& m = meta_;
  w.bytes(kDfmfSignature, std::strlen(kDfmfSignature));
  // Meta data, version 4 (write_meta_data.m), with its size computed from what is written.
  std::uint32_t metaSize = 4 + 4 + 3 * 80 + 4 + 12 + 4 + 4 + static_cast<std::uint32_t>(m.xml.size()) + 4;
  for (const std::string& n : m.channelNames) metaSize += 4 + static_cast<std::uint32_t>(n.size());
  w.value(metaSize);
  w.value(std::uint32_t{4});
  for (const std::string* s : {&m.measurementSetup, &m.imageSensor, &m.lightSource}) {
    char buf[80] = {};
    std::memcpy(buf, s->data(), std::min<std::size_t>(80, s->size()));
    w.bytes(buf, 80);
  }
  w.value(m.ppmm);
  for (float f : m.rgbScale) w.value(f);
  w.value(m.cosineFlag);
  w.value(static_cast<std::uint32_t>(m.xml.size()));
  w.bytes(m.xml.data(), m.xml.size());
  w.value(static_cast<std::uint32_t>(m.channelNames.size()));
  for (const std::string& n : m.channelNames) {
    w.value(static_cast<std::uint32_t>(n.size()));
    w.bytes(n.data(), n.size());
  }
  // Directions (write_bidir_sampling.m): the light list repeated for every view.
  w.value(static_cast<std::uint32_t>(m.views.size()));
  std::vector<float> lightAngles;
  for (const Direction& l : m.lights) {
    auto a = radiansFromDirection(l);
    lightAngles.push_back(a[0]), lightAngles.push_back(a[1]);
  }
  for (const Direction& v : m.views) {
    auto a = radiansFromDirection(v);
    w.value(a[0]), w.value(a[1]);
    w.value(static_cast<std::uint32_t>(m.lights.size()));
    w.bytes(lightAngles.data(), lightAngles.size() * 4);
  }
  w.value(static_cast<std::uint32_t>(m.width));
  w.value(static_cast<std::uint32_t>(m.height));
  w.value(static_cast<std::uint32_t>(m.rotations.size()));  // the signature ends in 'R'
  for (const auto& rot : m.rotations)
    for (float f : rot) w.value(f);
  // DFMF fields and channels (write_ubo_dfmf.m).
  std::uint32_t maxK = 0;
  for (const Ubo2014Channel& ch : channels_) maxK = std::max<std::uint32_t>(maxK, ch.components);
  w.value(maxK);
  w.value(m.colorModel);
  for (float f : m.colorMean) w.value(f);
  for (float f : m.colorTransform) w.value(f);
  for (const Ubo2014Channel& ch : channels_) {
    w.value(static_cast<std::uint8_t>(ch.scalarSize));
    w.value(static_cast<std::uint32_t>(ch.components));
    w.value(static_cast<std::uint32_t>(ch.uRows));
    w.value(static_cast<std::uint32_t>(ch.sxvRows));
    std::vector<float> s = ch.s;
    s.resize(ch.components, 0.0f);
    w.scalars(s, ch.scalarSize);
    w.scalars(ch.u, ch.scalarSize);
    w.scalars(ch.sxv, ch.scalarSize);
  }
  writeFileAtomic(path, w.out.data(), w.out.size());
}

}  // namespace nbtf
