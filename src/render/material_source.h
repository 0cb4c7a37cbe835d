// Where the renderer's surface colour comes from: one small interface over a compressed
// .nbtf (through the public decoder API) and an original image stack (the measured BTF,
// interpolated between measured directions). Queries are texture coordinates plus light
// and view unit vectors in the local frame (z = normal), exactly the decoder's UvQuery;
// answers are linear RGB (3 floats per query), un-normalized (x alpha for .nbtf files).
#pragma once
#include <array>
#include <memory>
#include <string>
#include <vector>

#include "codec/decoder.h"
#include "gltf/gltf_material.h"
#include "io/btf_stack.h"

namespace nbtf {

class MaterialSource {
 public:
  virtual ~MaterialSource() = default;
  virtual int width() const = 0;   // texels
  virtual int height() const = 0;
  virtual std::string name() const = 0;  // path or description, for messages and reports
  // Linear RGB for `count` queries into rgb (3 per query). Thread-safe; the caller batches
  // (the decoder's batch path is several times faster than single queries). Each result
  // depends on its own query only, so images do not depend on how queries are batched.
  virtual void evaluate(const UvQuery* queries, std::size_t count, float* rgb) const = 0;
};

// A .nbtf file through NbtfDecoder (OutputScale::Linear). Batches are cut into pieces
// small enough that the decoder stays on the calling thread (the renderer parallelizes
// over image tiles itself).
class NbtfMaterial : public MaterialSource {
 public:
  explicit NbtfMaterial(NbtfDecoder decoder) : decoder_(std::move(decoder)) {}
  int width() const override { return decoder_.width(); }
  int height() const override { return decoder_.height(); }
  std::string name() const override { return decoder_.name(); }
  void evaluate(const UvQuery* queries, std::size_t count, float* rgb) const override;
  const NbtfDecoder& decoder() const { return decoder_; }

 private:
  NbtfDecoder decoder_;
};

// Interpolation weights over a set of measured directions: the `k` nearest by angle,
// weighted by inverse squared angle (w_i = 1 / angle_i^2, normalized); a direction within
// 1e-6 rad of a measured one gets that one alone (weight 1).
struct DirectionWeights {
  int count = 0;
  std::array<int, 4> index{};
  std::array<float, 4> weight{};
};
class DirectionInterpolator {
 public:
  explicit DirectionInterpolator(const std::vector<Direction>& measured, int k = 3);
  DirectionWeights weights(const std::array<float, 3>& unit) const;  // unit: normalized here

 private:
  std::vector<std::array<double, 3>> dirs_;
  int k_;
};

// An original image stack: texel = floor(u * width) mod width (v likewise, as the decoder
// maps texture coordinates); the light and the view are each interpolated over their
// measured sets (DirectionInterpolator, k = 3), so a value is a weighted sum of up to
// 3 x 3 measured images at that texel.
class StackMaterial : public MaterialSource {
 public:
  explicit StackMaterial(BtfStack stack, std::string name = "");
  int width() const override { return stack_.width(); }
  int height() const override { return stack_.height(); }
  std::string name() const override { return name_; }
  void evaluate(const UvQuery* queries, std::size_t count, float* rgb) const override;
  const BtfStack& stack() const { return stack_; }

 private:
  BtfStack stack_;
  std::string name_;
  DirectionInterpolator lights_, views_;
};

// A fitted glTF material (gltf/gltf_read.h): per texel the glTF 2.0 BRDF x exposure x the
// cosine at the texel's shading normal (the convention of gltf/gltf_material.h), at the texel
// the decoder would use (floor(u * width) mod width, likewise v): nearest, as glTF's NEAREST
// magnification filter samples it.
class GltfMaterialSource : public MaterialSource {
 public:
  GltfMaterialSource(gltf::GltfMaterial material, std::string name)
      : material_(std::move(material)), name_(std::move(name)) {}
  int width() const override { return material_.width; }
  int height() const override { return material_.height; }
  std::string name() const override { return name_; }
  void evaluate(const UvQuery* queries, std::size_t count, float* rgb) const override;
  const gltf::GltfMaterial& material() const { return material_; }

 private:
  gltf::GltfMaterial material_;
  std::string name_;
};

// Texel index of texture coordinate u in a texture `size` texels wide (wraps).
int wrapTexel(double u, int size);

// Opens `path`: a .nbtf file (by its magic bytes), a glTF file (.gltf) or an image stack
// folder (loaded with `crop`). Throws nbtf::Error naming the path when it does not exist or is neither.
std::unique_ptr<MaterialSource> openMaterial(const std::string& path, const Crop& crop = {}, bool progress = true);

}  // namespace nbtf
