#include "eval/compressed_source.h"

#include <algorithm>
#include <cmath>

#include "codec/methods/method.h"
#include "codec/texel_modulation.h"
#include "util/error.h"

#include <nlohmann/json.hpp>

namespace nbtf {

std::vector<int> clusterGenerationsOf(const CompressedBtf& btf) {
  std::vector<int> out;
  const nlohmann::json meta = nlohmann::json::parse(btf.metadataJson, nullptr, false);
  if (!meta.is_object() || !meta.contains("adaptive") || !meta["adaptive"].is_object()) return out;
  const nlohmann::json& g = meta["adaptive"]["generation"];
  if (!g.is_string()) return out;
  const std::string digits = g.get<std::string>();
  if (static_cast<int>(digits.size()) != btf.latentRows) return out;  // not this file's clusters: ignore
  for (char ch : digits) {
    const int v = ch >= '0' && ch <= '9' ? ch - '0' : ch >= 'a' && ch <= 'z' ? ch - 'a' + 10 : -1;
    if (v < 0) return {};
    out.push_back(v);
  }
  return out;
}

CompressedReconstruction::CompressedReconstruction(const CompressedBtf& btf, const std::string& name)
    : decoder_(btf, DecoderOptions{}, name) {}  // the decoder validates the shapes (CompressedBtf::validate)

void CompressedReconstruction::image(int image, float* out) const {
  const int nv = static_cast<int>(decoder_.views().size());
  // Images are decoded in parallel by the caller, so each decode runs on one thread.
  decoder_.decodeImage(decoder_.lights().at(static_cast<std::size_t>(image / nv)),
                       decoder_.views().at(static_cast<std::size_t>(image % nv)), out, OutputScale::Linear, 0, 0,
                       false);
}

void checkReferenceMatches(const CompressedBtf& btf, const BtfStack& ref, const std::string& fileName,
                           const std::string& referenceName) {
  const std::string prefix = "reference '" + referenceName + "' does not match '" + fileName + "': ";
  if (ref.width() != btf.width || ref.height() != btf.height) {
    std::string crop = btf.crop.empty() ? "the whole image"
                                        : "crop " + std::to_string(btf.crop.x) + "," + std::to_string(btf.crop.y) + "," +
                                              std::to_string(btf.crop.width) + "," + std::to_string(btf.crop.height);
    throw Error(prefix + "texel size is " + std::to_string(ref.width()) + " x " + std::to_string(ref.height()) +
                " in the reference but " + std::to_string(btf.width) + " x " + std::to_string(btf.height) +
                " in the file (which was made from " + crop + " of " + std::to_string(btf.sourceWidth) + " x " +
                std::to_string(btf.sourceHeight) + " images)");
  }
  checkSameDirections(ref.lights(), btf.lights, "light", prefix);
  checkSameDirections(ref.views(), btf.views, "view", prefix);
}

SizeTable sizeTableOf(const CompressedBtf& btf, std::uint64_t fileBytes) {
  NbtfSizes s = computeSizes(btf, fileBytes);
  SizeTable t;
  t.rawFloat32 = s.rawFloat32, t.decoder = s.decoder, t.latents = s.latents, t.ids = s.ids, t.total = s.total;
  t.perTexel = s.modulation;
  t.planes = s.planes;
  t.clusterPlanes = s.clusterPlanes;
  t.fileBytes = s.fileBytes;
  t.idsPaper = s.idsPaper, t.totalPaper = s.totalPaper;
  t.pca = s.pca, t.pcaComponents = s.pcaComponents;
  t.pcaMean = s.pcaMean, t.pcaBasis = s.pcaBasis, t.pcaCoefficients = s.pcaCoefficients;
  return t;
}

EvalInputs compressedEvalInputs(const CompressedBtf& btf, const BtfStack& reference,
                                const CompressedReconstruction& reconstruction, const std::string& fileName,
                                const std::string& referenceName, std::uint64_t fileBytes) {
  EvalInputs in;
  in.reference = &reference;
  in.alpha = btf.alpha;
  in.reconstruct = [&reconstruction](int image, float* out) { reconstruction.image(image, out); };
  in.holdoutImages = btf.holdoutImages;
  in.sizes = sizeTableOf(btf, fileBytes);
  const MethodKind& kind = methodKind(btf.method, fileName);
  in.method = kind.label(btf);
  in.methodParameter = kind.sweepParameter(btf);
  // Modulated files are a curve of their own in sweeps (they are not the paper's model).
  in.methodFamily = std::string(kind.name()) + (btf.modulation.empty() ? "" : "-modulated") +
                    (btf.planes.empty() ? "" : "-planes") + (btf.clusterPlanes.empty() ? "" : "-cluster-planes");
  if (btf.method == CodecMethod::ClusteredNeural) {
    in.clusterIds = btf.ids;
    in.clusters = btf.latentRows;
    in.clusterGenerations = clusterGenerationsOf(btf);
    if (!in.clusterGenerations.empty()) in.methodFamily += "-adaptive";  // a curve of its own in sweeps
    if (!btf.modulation.empty()) {
      // The floor of any model mixing per-cluster terms with the file's coefficients: their
      // span per cluster, made orthonormal as clusterValues needs.
      in.texelCoefficients = orthonormalizeTexelCoefficients(reconstruction.decoder().texelCoefficients(),
                                                             btf.modulation.terms, btf.ids, btf.latentRows,
                                                             btf.modulation.channels);
      in.coefficientTerms = btf.modulation.terms;
      in.coefficientChannels = btf.modulation.channels;
    }
  }
  in.referenceName = referenceName;
  in.compressedName = fileName;
  if (btf.isPca()) {
    in.details = {{"method", kind.name()},
                  {"PCA components", std::to_string(btf.latentDim)},
                  {"data", "linear RGB / alpha, mean-centred"},
                  {"unmeasured directions", "mean and basis interpolated over the nearest measured pairs"},
                  {"texel evaluations per image", std::to_string(reconstruction.evaluationsPerImage())},
                  {"held-out images", std::to_string(btf.holdoutImages.size()) +
                                          (btf.holdoutImages.empty() ? "" : " (left out of the fit, interpolated)")}};
    return in;
  }
  std::string shape = std::to_string(btf.decoder.inputSize());
  for (const auto& layer : btf.decoder.layers) shape += " -> " + std::to_string(layer.out);
  in.details = {{"method", kind.name()},
                {"latent rows (k or texels)", std::to_string(btf.latentRows)},
                {"latent dimension", std::to_string(btf.latentDim)},
                {"decoder", shape + " (" + std::to_string(btf.decoder.parameterCount()) + " parameters)"},
                {"decoder evaluations per image", std::to_string(reconstruction.evaluationsPerImage())},
                {"held-out images", std::to_string(btf.holdoutImages.size())}};
  if (!btf.modulation.empty())
    in.details.push_back({"per-texel modulation", modulationDescription(btf.modulation)});
  if (btf.storage.anyCompact())
    in.details.push_back({"storage", storageDescription(btf)});
  return in;
}

}  // namespace nbtf
