// The config file of `nbtf compress`: the training recipe (model, optimizer, training,
// modulation, storage: loadTrainConfig's objects), the "clustering" object (the default k and
// the space the clusters are found in) and the "adaptive" object, which turns on adaptive clusters and sets
// their targets (pipeline/adaptive.h). The command line's --clusters, --cluster-space, --adaptive,
// --target-rmse, ... override the file's values.
#pragma once
#include <string>

#include "pipeline/compressor.h"

namespace nbtf {

struct CompressConfig {
  TrainConfig train;
  AdaptiveOptions adaptive;  // the "adaptive" object ("enabled": false when absent)
  ClusteringSpace clusteringSpace = kDefaultClusteringSpace;  // the "clustering" object's "space"
  int clusters = kDefaultClusters;  // its "clusters": k without --clusters (0 = per-texel), capped to small inputs
  // Its "texels_per_cluster" (instead of "clusters"; 0 = not given): k = texels / this without
  // --clusters, so that the point's ratio holds on every size of input.
  double texelsPerCluster = 0;
};

// Loads a compress config; unknown keys, wrong types and out-of-range values are errors that
// name the file and the key.
CompressConfig loadCompressConfig(const std::string& path);

// Throws nbtf::Error naming `source` ("<file>", "command line"), the config key and its
// command-line option when a value is out of range. 0 means "none" for the targets.
void validateAdaptiveOptions(const AdaptiveOptions& adaptive, const std::string& source);

// The "adaptive" object in the config-file format (every key, so a file's metadata says
// exactly what ran; reloadable by loadCompressConfig).
std::string adaptiveConfigJson(const AdaptiveOptions& adaptive);

}  // namespace nbtf
