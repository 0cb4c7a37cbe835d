#include "render/material_source.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "gltf/gltf_read.h"
#include "io/btf_loader.h"
#include "io/ubo2014_btf.h"
#include "util/error.h"

namespace nbtf {

namespace {
// Below the decoder's own threshold for running a batch on several threads.
constexpr std::size_t kDecoderPiece = 2048;
}  // namespace

void NbtfMaterial::evaluate(const UvQuery* queries, std::size_t count, float* rgb) const {
  for (std::size_t begin = 0; begin < count; begin += kDecoderPiece)
    decoder_.evaluate(queries + begin, std::min(kDecoderPiece, count - begin), rgb + 3 * begin, OutputScale::Linear);
}

DirectionInterpolator::DirectionInterpolator(const std::vector<Direction>& measured, int k)
    : k_(std::clamp(k, 1, 4)) {
  if (measured.empty()) throw Error("a material needs at least one measured direction");
  for (const Direction& d : measured) dirs_.push_back(d.unitVector());
  k_ = std::min<int>(k_, static_cast<int>(dirs_.size()));
}

DirectionWeights DirectionInterpolator::weights(const std::array<float, 3>& unit) const {
  const double n = std::sqrt(double(unit[0]) * unit[0] + double(unit[1]) * unit[1] + double(unit[2]) * unit[2]);
  const double x = unit[0] / n, y = unit[1] / n, z = unit[2] / n;
  // The k largest cosines (= smallest angles), in order.
  std::array<double, 4> bestCos;
  bestCos.fill(-2);
  DirectionWeights w;
  w.count = k_;
  for (int i = 0; i < static_cast<int>(dirs_.size()); ++i) {
    const double c = x * dirs_[i][0] + y * dirs_[i][1] + z * dirs_[i][2];
    for (int j = 0; j < k_; ++j) {
      if (c > bestCos[j]) {
        for (int m = k_ - 1; m > j; --m) bestCos[m] = bestCos[m - 1], w.index[m] = w.index[m - 1];
        bestCos[j] = c, w.index[j] = i;
        break;
      }
    }
  }
  const double angle0 = std::acos(std::clamp(bestCos[0], -1.0, 1.0));
  if (angle0 < 1e-6) {
    w.count = 1;
    w.weight[0] = 1;
    return w;
  }
  double sum = 0;
  std::array<double, 4> raw{};
  for (int j = 0; j < k_; ++j) {
    const double a = std::acos(std::clamp(bestCos[j], -1.0, 1.0));
    raw[j] = 1.0 / (a * a);
    sum += raw[j];
  }
  for (int j = 0; j < k_; ++j) w.weight[j] = static_cast<float>(raw[j] / sum);
  return w;
}

int wrapTexel(double u, int size) {
  if (!std::isfinite(u)) throw Error("texture coordinate is not finite");
  double f = std::floor(u * size);
  long long t = static_cast<long long>(f) % size;
  if (t < 0) t += size;
  return static_cast<int>(t);
}

StackMaterial::StackMaterial(BtfStack stack, std::string name)
    : stack_(std::move(stack)), name_(name.empty() ? stack_.source : std::move(name)),
      lights_(stack_.lights()), views_(stack_.views()) {
  if (stack_.numTexels() == 0) throw Error(name_ + ": the image stack is empty");
}

void StackMaterial::evaluate(const UvQuery* queries, std::size_t count, float* rgb) const {
  for (std::size_t i = 0; i < count; ++i) {
    const UvQuery& q = queries[i];
    if (q.light[2] < 0 || q.view[2] < 0)
      throw Error(name_ + ": query " + std::to_string(i) + " has a direction below the surface (z < 0)");
    const int texel = wrapTexel(q.v, stack_.height()) * stack_.width() + wrapTexel(q.u, stack_.width());
    const DirectionWeights wl = lights_.weights(q.light), wv = views_.weights(q.view);
    double acc[3] = {0, 0, 0};
    for (int a = 0; a < wl.count; ++a)
      for (int b = 0; b < wv.count; ++b) {
        const int image = stack_.imageIndex(wl.index[a], wv.index[b]);
        const double w = double(wl.weight[a]) * wv.weight[b];
        for (int c = 0; c < 3; ++c) acc[c] += w * stack_.sample(image, texel, c);
      }
    for (int c = 0; c < 3; ++c) rgb[3 * i + c] = static_cast<float>(acc[c]);
  }
}

void GltfMaterialSource::evaluate(const UvQuery* queries, std::size_t count, float* rgb) const {
  for (std::size_t i = 0; i < count; ++i) {
    const UvQuery& q = queries[i];
    const int texel = wrapTexel(q.v, material_.height) * material_.width + wrapTexel(q.u, material_.width);
    const gltf::Vec3 l{q.light[0], q.light[1], q.light[2]}, v{q.view[0], q.view[1], q.view[2]};
    const gltf::Vec3 value = material_.value(texel, l, v);
    for (int c = 0; c < 3; ++c) rgb[3 * i + c] = static_cast<float>(value[c]);
  }
}

std::unique_ptr<MaterialSource> openMaterial(const std::string& path, const Crop& crop, bool progress) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec))
    throw fileError(path, "no such file or folder (expected a .nbtf file, an image stack folder or a UBO2014 .btf file)");
  if (std::filesystem::is_directory(path, ec) || looksLikeUbo2014(path)) {  // a stack, or a UBO2014 .btf file
    LoadOptions options;
    options.crop = crop;
    options.progress = progress;
    return std::make_unique<StackMaterial>(loadBtfStack(path, options), path);
  }
  if (!crop.empty()) throw Error("--crop applies to image stacks; " + path + " is a file");
  if (gltf::isGltfPath(path)) return std::make_unique<GltfMaterialSource>(gltf::readGltfMaterial(path), path);
  if (!hasNbtfMagic(path))
    throw fileError(path, "not a .nbtf file (no nbtf magic bytes) and not an image stack folder");
  return std::make_unique<NbtfMaterial>(NbtfDecoder::open(path));
}

}  // namespace nbtf
