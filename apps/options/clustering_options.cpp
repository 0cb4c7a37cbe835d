#include "options/clustering_options.h"

#include <string>

#include "util/error.h"

namespace nbtf::cli {

void addClusteringOptions(cxxopts::Options& options) {
  options.add_options("Clustering")(
      "k,clusters",
      "k, the number of clusters. compress: 0 = per-texel (one latent per texel); default the config's "
      "clustering.clusters (1000 in the default config), capped to one cluster per 10 texels on a small input. "
      "cluster: required",
      cxxopts::value<int>())(
      "components",
      "PCA components before k-means (default 32; compress caps it by the data); with compress --method pca the "
      "components kept (required there)",
      cxxopts::value<int>())(
      "cluster-space",
      "Values PCA and k-means work on: log (standardized log ABRDFs, the paper's) or linear (linear / alpha, where "
      "the error is measured); default linear (compress: the config's clustering.space). The representatives are "
      "medians of the standardized log ABRDFs either way",
      cxxopts::value<std::string>())(
      "seed", "Random seed: the same seed gives the same clusters (compress: and the same training) (default 1, or "
              "the config's training.seed)",
      cxxopts::value<long long>());
}

ClusteringArgs clusteringArgs(const cxxopts::ParseResult& args) {
  ClusteringArgs c;
  if (args.count("clusters")) {
    c.clusters = args["clusters"].as<int>();
    if (*c.clusters < 0) throw Error("--clusters must be >= 0 (0 = per-texel), got " + std::to_string(*c.clusters));
  }
  if (args.count("components")) {
    c.components = args["components"].as<int>();
    if (*c.components < 0) throw Error("--components must be >= 0, got " + std::to_string(*c.components));
  }
  if (args.count("cluster-space"))
    c.space = parseClusteringSpace(args["cluster-space"].as<std::string>(), "--cluster-space");
  if (args.count("seed")) {
    const long long seed = args["seed"].as<long long>();
    if (seed < 0) throw Error("--seed must be >= 0, got " + std::to_string(seed));
    c.seed = static_cast<std::uint64_t>(seed);
  }
  return c;
}

}  // namespace nbtf::cli
