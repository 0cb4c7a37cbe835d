// `nbtf cluster` without its command line: the clustering stage of compress alone on one
// input (the memory check and the stack's place, load, the standardization's statistics, PCA
// and k-means++ in the chosen space), and the files it writes: labels.png (the id list, a
// colour per cluster), texel_colour.png and cluster_colour.png (each texel's mean colour over
// all images, and its cluster's, on one scale) and summary.json (cluster/cluster_output.h).
#pragma once
#include <cstddef>
#include <string>

#include "cluster/cluster_output.h"
#include "cluster/clustering.h"
#include "io/btf_loader.h"
#include "pipeline/memory_estimate.h"

namespace nbtf {

struct ClusterStackOptions {
  ClusteringOptions clustering;
  ClusteringSpace space = kDefaultClusteringSpace;
  LoadOptions load;                // layout, crop
  std::size_t memoryLimit = 0;     // 0 = defaultMemoryLimit()
  std::string memoryLimitText;     // how the limit was given, for the error ("" = the default)
  StackStorageOptions stackStorage;
  bool progress = true;
};

struct ClusterStackRun {
  ClusteringResult result;
  ClusterRunInfo info;
  std::size_t memoryLimit = 0;  // the limit the run was held to
  Eigen::MatrixXf texelColour;  // texels x 3, linear RGB averaged over every image
};

// Refuses, before the stack is read, a run above the memory limit or asking for more
// clusters than texels or more components than the data has; `outDir` (which may not exist
// yet) places a scratch file when the stack goes to one. Throws nbtf::Error naming the input.
ClusterStackRun clusterStack(const std::string& input, const std::string& outDir, const ClusterStackOptions& options);

struct ClusterOutputFiles {
  std::string labels, texelColour, clusterColour, summary;
  nlohmann::json summaryJson;
};
// Creates `outDir` (and its parents) and writes the four files, each atomically.
ClusterOutputFiles writeClusterOutputs(const ClusterStackRun& run, const ClusterStackOptions& options,
                                       const std::string& outDir);

}  // namespace nbtf
