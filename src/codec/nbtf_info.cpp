#include "codec/nbtf_info.h"

#include <nlohmann/json.hpp>

#include "util/directions.h"
#include "util/layout.h"

namespace nbtf {

nlohmann::json nbtfPartBytes(const NbtfSizes& s) {
  nlohmann::json j;
  if (s.pca) {
    j = {{"pca_mean", s.pcaMean},
         {"pca_basis", s.pcaBasis},
         {"pca_coefficients", s.pcaCoefficients},
         {"pca_components", s.pcaComponents}};
  } else {
    j = {{"decoder", s.decoder},
         {"latents", s.latents},
         {"ids", s.ids},
         {"modulation", s.modulation},
         {"planes", s.planes},
         {"cluster_planes", s.clusterPlanes},
         {"decoder_parameters", s.decoderParameters},
         {"latent_rows", s.latentRows},
         {"latent_dim", s.latentDim},
         {"ids_paper", s.idsPaper},
         {"total_paper", s.totalPaper},
         {"ratio_paper", s.ratioPaper}};
  }
  j["total"] = s.total;
  j["raw_float32"] = s.rawFloat32;
  j["file"] = s.fileBytes;
  j["ratio"] = s.ratio;
  return j;
}

std::string nbtfInfoJson(const CompressedBtf& btf, const std::string& path, std::uint64_t fileBytes) {
  const NbtfSizes sizes = computeSizes(btf, fileBytes);
  nlohmann::json j;
  j["kind"] = "nbtf";
  j["file"] = path;
  j["format_version"] = std::to_string(btf.formatMajor) + "." + std::to_string(btf.formatMinor);
  j["method"] = codecMethodName(btf.method);
  j["width"] = btf.width;
  j["height"] = btf.height;
  j["image_size"] = {btf.sourceWidth, btf.sourceHeight};
  j["crop"] = btf.crop.empty() ? nlohmann::json(nullptr)
                               : nlohmann::json{btf.crop.x, btf.crop.y, btf.crop.width, btf.crop.height};
  j["layout"] = layoutName(btf.layout);
  j["lights"] = btf.lights.size();
  j["views"] = btf.views.size();
  j["images"] = btf.numImages();
  j["clusters"] = btf.numClusters();
  j["latent_dim"] = btf.latentDim;
  j["latent_rows"] = btf.latentRows;
  if (!btf.isPca()) j["direction_inputs"] = directionEncodingName(btf.directionEncoding);
  j["pca_components"] = btf.pcaComponents();
  j["alpha"] = btf.alpha;
  j["holdout_images"] = btf.holdoutImages.size();
  j["bytes"] = nbtfPartBytes(sizes);
  j["ratio"] = sizes.ratio;
  nlohmann::json meta = nlohmann::json::parse(btf.metadataJson, nullptr, /*allow_exceptions=*/false);
  j["metadata"] = meta.is_discarded() ? nlohmann::json(nullptr) : meta;
  return j.dump(2);
}

}  // namespace nbtf
