// The clustering options `nbtf compress` and `nbtf cluster` share, declared and read once: one
// name, one type and one check each (as COLMAP's option manager binds one struct for every
// command). Values not given stay unset, so each command applies its own defaults (compress:
// its config's; cluster: PCA's and k-means++'s own).
#pragma once
#include <cstdint>
#include <cxxopts.hpp>
#include <optional>

#include "cluster/clustering.h"

namespace nbtf::cli {

struct ClusteringArgs {
  std::optional<int> clusters;           // -k / --clusters, >= 0
  std::optional<int> components;         // --components, >= 0
  std::optional<ClusteringSpace> space;  // --cluster-space
  std::optional<std::uint64_t> seed;     // --seed, >= 0
};

// Adds the group "Clustering": -k/--clusters, --components, --cluster-space, --seed.
void addClusteringOptions(cxxopts::Options& options);
// The values given, checked (nbtf::Error naming the option).
ClusteringArgs clusteringArgs(const cxxopts::ParseResult& args);

}  // namespace nbtf::cli
