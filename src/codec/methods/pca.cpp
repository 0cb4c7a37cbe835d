// The PCA kind (the classic baseline, codec/pca_model.h): a mean and a basis per image channel,
// C coefficients per texel, no decoder. Unmeasured directions interpolate the mean and the basis
// over the nearest measured pairs.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

#include "codec/methods/evaluator.h"
#include "codec/methods/method.h"
#include "codec/nbtf_format.h"
#include "codec/pca_model.h"
#include "util/error.h"
#include "util/parallel.h"

namespace nbtf {
namespace {

using format::kMaxPcaComponents;
using format::Need;
using format::Part;

// The kind's shape (C components, one coefficient row per texel) before its parts' checks,
// which size the mean, basis and coefficients by it.
void validatePca(const CompressedBtf& btf, const std::string& name) {
  auto fail = [&](const std::string& message) { return fileError(name, message); };
  const std::int64_t rows = 3 * static_cast<std::int64_t>(btf.numImages());
  const int texels = btf.numTexels();
  if (!btf.decoder.layers.empty() || !btf.ids.empty()) throw fail("PCA file has a decoder or an id list");
  if (!btf.planes.values.empty() || !btf.clusterPlanes.values.empty()) throw fail("PCA file has direction or cluster planes");
  const std::int64_t maxComponents = std::min<std::int64_t>({rows, texels, kMaxPcaComponents});
  if (btf.latentDim < 1 || btf.latentDim > maxComponents)
    throw fail(std::to_string(btf.latentDim) + " PCA components, expected 1 to " + std::to_string(maxComponents) +
               " (at most min(texels, 3 x images))");
  if (btf.latentRows != texels)
    throw fail("PCA file has " + std::to_string(btf.latentRows) + " coefficient rows for " + std::to_string(texels) +
               " texels");
  checkStoredParts(btf, methodKind(btf.method), name);
}

// Per (light, view) the mean and basis rows are combined once, then each texel costs 3 dot
// products of length C.
class PcaEvaluator final : public detail::MaterialEvaluator {
 public:
  explicit PcaEvaluator(const CompressedBtf& btf)
      : interpolator_(btf.lights, btf.views), components_(btf.latentDim) {}

  // 3 dot products of length C (the per-image basis combination not counted).
  double flopsPerEvaluation() const override { return 6.0 * components_; }

  void evaluate(const NbtfDecoder& d, const TexelQuery* queries, std::size_t count, float* rgb,
                OutputScale scale) const override {
    evaluateQueries(d, count, rgb, scale, [&](std::size_t i, int& texel, std::array<double, 3>& l, std::array<double, 3>& v) {
      const TexelQuery& q = queries[i];
      texel = q.y * d.width() + q.x;
      l = q.light.unitVector();
      v = q.view.unitVector();
    });
  }

  void evaluate(const NbtfDecoder& d, const UvQuery* queries, std::size_t count, float* rgb,
                OutputScale scale) const override {
    evaluateQueries(d, count, rgb, scale, [&](std::size_t i, int& texel, std::array<double, 3>& l, std::array<double, 3>& v) {
      const UvQuery& q = queries[i];
      texel = d.texelOfUv(q.u, q.v);
      l = unitQueryVector(q.light, "light");  // checked by the decoder: these do not throw
      v = unitQueryVector(q.view, "view");
    });
  }

  // The basis at this pair once, then 3 dot products of length C per texel.
  void decodeRows(const NbtfDecoder& d, const Direction& light, const Direction& view, float* rgb, OutputScale scale,
                  bool parallel) const override {
    const CompressedBtf& m = d.material();
    const int c = m.latentDim;
    std::vector<float> meanBasis(3 + 3 * static_cast<std::size_t>(c));
    basisAt(m, light.unitVector(), view.unitVector(), meanBasis.data());
    const float factor = m.alpha;
    auto body = [&](std::size_t begin, std::size_t end) {
      for (std::size_t t = begin; t < end; ++t) {
        float* out = rgb + 3 * t;
        pcaTexelValue(m.latents.data() + t * c, meanBasis.data(), meanBasis.data() + 3, c, out);
        if (scale == OutputScale::Linear) out[0] *= factor, out[1] *= factor, out[2] *= factor;
      }
    };
    const std::size_t texels = static_cast<std::size_t>(m.numTexels());
    if (parallel && texels >= detail::kMinParallelSamples) parallelFor(texels, body, 1024);
    else body(0, texels);
  }

  void decodeRowTerms(const NbtfDecoder& d, const Direction&, const Direction&, float*, bool) const override {
    throw Error(d.name() + ": decodeRowTerms: a PCA file has no decoder terms");
  }

 private:
  // The mean (3) and basis (3 x C) at a pair of unit vectors, into meanBasis.
  void basisAt(const CompressedBtf& m, const std::array<double, 3>& light, const std::array<double, 3>& view,
               float* meanBasis) const {
    combinePcaRows(m.pcaMean.data(), m.pcaBasis.data(), m.latentDim, interpolator_.weights(light, view), meanBasis,
                   meanBasis + 3);
  }

  // `count` queries; query(i, texel, light, view) gives query i (unit vectors).
  template <class QueryFn>
  void evaluateQueries(const NbtfDecoder& d, std::size_t count, float* rgb, OutputScale scale,
                       const QueryFn& query) const {
    const CompressedBtf& m = d.material();
    const int c = m.latentDim;
    auto body = [&](std::size_t begin, std::size_t end) {
      // Consecutive queries often share their directions: combine the basis once for them.
      std::vector<float> meanBasis(3 + 3 * static_cast<std::size_t>(c));
      std::array<double, 3> lastLight{}, lastView{};
      bool have = false;
      for (std::size_t i = begin; i < end; ++i) {
        int texel = 0;
        std::array<double, 3> l, v;
        query(i, texel, l, v);
        if (!have || l != lastLight || v != lastView) {
          basisAt(m, l, v, meanBasis.data());
          lastLight = l, lastView = v, have = true;
        }
        float* out = rgb + 3 * i;
        pcaTexelValue(m.latents.data() + static_cast<std::size_t>(texel) * c, meanBasis.data(), meanBasis.data() + 3,
                      c, out);
        if (scale == OutputScale::Linear) out[0] *= m.alpha, out[1] *= m.alpha, out[2] *= m.alpha;
      }
    };
    if (count >= detail::kMinParallelSamples) parallelFor(count, body, 1024);
    else body(0, count);
  }

  DirectionInterpolator interpolator_;
  int components_ = 0;
};

class Pca final : public MethodKind {
 public:
  Pca() : MethodKind(CodecMethod::Pca, "pca", "PCA") {}
  // Every Part listed, no default: the compiler names the kinds a new part must be added to.
  Need need(Part part) const override {
    switch (part) {
      case Part::Info:
      case Part::Directions:
      case Part::PcaMean:
      case Part::PcaBasis:
      case Part::PcaCoefficients: return Need::Required;
      case Part::Decoder:
      case Part::Latents:
      case Part::Ids:
      case Part::Modulation:
      case Part::ClusterPlanes: return Need::Forbidden;
      case Part::Planes:
      case Part::Holdout:
      case Part::Encoder:
      case Part::Metadata: return Need::Optional;
    }
    return Need::Forbidden;
  }
  std::string summary(const CompressedBtf& btf) const override {
    return std::string(name()) + " (classic baseline), C = " + std::to_string(btf.latentDim) + " components";
  }
  std::string label(const CompressedBtf& btf) const override { return "PCA, C = " + std::to_string(btf.latentDim); }
  std::vector<std::pair<std::string, std::string>> infoFields(const CompressedBtf& btf) const override {
    char alpha[64];
    std::snprintf(alpha, sizeof alpha, "%.6g", btf.alpha);
    const std::string c = std::to_string(btf.latentDim), rows = std::to_string(3 * btf.numImages());
    return {{"alpha", std::string(alpha) + " ((mean + coefficients x basis) x alpha = linear RGB)"},
            {"mean", rows + " values (3 per image)"},
            {"basis", rows + " rows (3 per image) x " + c + " components"},
            {"coefficients", std::to_string(btf.latentRows) + " texels x " + c + " components"},
            {"interpolation", "unmeasured directions: mean and basis blended over the " +
                                  std::to_string(kPcaNeighbours) + " nearest measured (light, view) pairs"}};
  }
  int sweepParameter(const CompressedBtf& btf) const override { return btf.latentDim; }
  void validate(const CompressedBtf& btf, const std::string& name) const override { validatePca(btf, name); }
  std::unique_ptr<detail::MaterialEvaluator> evaluator(const CompressedBtf& btf, DecoderIsa,
                                                       const DecoderOptions&) const override {
    return std::make_unique<PcaEvaluator>(btf);
  }
};

}  // namespace

const MethodKind& pcaMethod() {
  static const Pca kind;
  return kind;
}

}  // namespace nbtf
