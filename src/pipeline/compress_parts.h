// The pieces every compressor of a model kind shares (pipeline/neural_compressor.cpp,
// adaptive.cpp, pca_compressor.cpp): the file's frame and provenance, the decoded RMSE, and the
// assembly of trained parts into a material. They call nothing above them. PRIVATE to
// src/pipeline.
#pragma once
#include <string>
#include <utility>
#include <vector>
#include <nlohmann/json.hpp>

#include "cluster/clustering.h"
#include "codec/decoder.h"
#include "pipeline/compressor.h"

namespace nbtf {

// A compressed material's description of its source, common to every method: size, crop,
// source size, layout, sample type, directions, alpha. The method's own parts are left empty.
CompressedBtf compressedFrame(const BtfStack& stack, CodecMethod method, float alpha);
// The "source" object of the file's metadata (path, layout, sample type, crop) as JSON text.
std::string sourceMetadataJson(const BtfStack& stack);

namespace detail {

// PCA components of the clustering when --components is not given (capped by the data).
constexpr int kDefaultPcaComponents = 32;

inline bool stopRequested(const CompressOptions& o) { return o.stopFlag && o.stopFlag->load(); }
// A figure that may be absent (< 0) as JSON: the number, or null.
inline nlohmann::json jsonOrNull(double v) { return v < 0 ? nlohmann::json(nullptr) : nlohmann::json(v); }

// Provenance stored in the file (no timings or paths: the same seed gives the same bytes).
// `adaptiveJson`: the "adaptive" object (stages, generations), "" = none.
std::string metadataJson(const BtfStack& stack, const TrainConfig& config,
                         const TrainResult& train, const ClusteringResult* clustering, int pcaComponents,
                         const CompressStats& stats, const std::string& adaptiveJson);

// RMSE (eq. 10, linear / alpha) of what `decoder` decodes, on the training and the held-out
// images (-1 when none). Independent of the thread count. A modulated material may pass, per
// image, the terms decodeRowTerms already gave there (null: decoded here); the result is the
// same to the bit, without evaluating the network again.
std::pair<double, double> decodedRmse(const NbtfDecoder& decoder, const BtfStack& stack, float alpha,
                                      const std::vector<std::uint8_t>& holdout,
                                      const std::vector<const float*>& rowTerms = {});

// The per-texel coefficients training uses for a clustering: a rank-`terms` SVD per cluster
// (and channel, with channels 3) over the training images, orthonormalized per cluster.
std::vector<float> trainingCoefficients(const BtfStack& stack, float alpha, const std::vector<std::int32_t>& ids,
                                        int clusters, const std::vector<std::uint8_t>& holdout,
                                        const ModulationConfig& modulation, bool progress);

// How `storage` stores a material's parts; clusterPlanes: whether it has per-cluster planes.
PartStorage partStorage(const StorageConfig& storage, bool clusterPlanes);

// Whether assembleCompressed measures the decoded file under `config` (its decoder or latents
// rounded, or per-texel modulation refit): then training's own final evaluation is not needed.
bool assemblyMeasures(const TrainConfig& config, int clusters);

// The trained parts -> a compressed material: decoder, latents, ids, hold-out list, storage
// rounding and (modulated) the per-texel coefficients refit to the trained terms. When
// rounding or modulation changes what the file decodes to, or training did not measure it
// (train.rmseTrain < 0), train.rmseTrain / rmseHoldout become the decoded RMSE. Moves the
// decoder, latents and encoder state out of `train`.
CompressedBtf assembleCompressed(const BtfStack& stack, const TrainConfig& config, CodecMethod method, float alpha,
                                 TrainResult& train, std::vector<std::int32_t> ids, int clusters,
                                 const std::vector<float>& texelCoefficients, const std::vector<int>& trainImages,
                                 const std::vector<std::uint8_t>& holdout, bool progress);

}  // namespace detail
}  // namespace nbtf
