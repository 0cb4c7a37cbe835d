// The clustering stage as a whole: PCA of the ABRDFs (standardized log, or linear: the
// clustering space), k-means++ over texels, and one representative standardized ABRDF per
// cluster (per-dimension median, the paper's choice).
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "cluster/kmeans.h"
#include "cluster/pca.h"

namespace nbtf {

enum class Representative { Median, Mean };

// The values PCA and k-means find the clusters in (docs/clustering.md, *Clustering space*): the
// standardized log ABRDFs (the paper's), or the linear ABRDFs / alpha, the space the error is
// measured in.
enum class ClusteringSpace { Log, Linear };
constexpr ClusteringSpace kDefaultClusteringSpace = ClusteringSpace::Linear;  // configs/default.json's
const char* clusteringSpaceName(ClusteringSpace space);  // "log", "linear"
// "log" or "linear"; anything else throws nbtf::Error naming `where` (an option or a key).
ClusteringSpace parseClusteringSpace(const std::string& text, const std::string& where);
// The `space` argument of clusterAbrdfs for a stack: the linear source (alpha: eq. 5), or
// nullptr for the log space (the standardized source itself).
std::unique_ptr<StackAbrdfSource> clusteringSpaceSource(const BtfStack& stack, ClusteringSpace space, float alpha);

struct ClusteringOptions {
  int clusters = 500;
  PcaOptions pca;        // seed and progress are taken from here
  KMeansOptions kmeans;  // clusters, seed and progress are taken from here
  Representative representative = Representative::Median;
  std::uint64_t seed = 1;
  bool progress = true;
  bool keepScores = false;  // return the texels' PCA scores (adaptive clustering splits in that space)
};

struct ClusteringResult {
  std::vector<std::int32_t> ids;  // M
  MatrixXfCol representatives;    // k x D, in the same space as the input X (standardized)
  std::vector<int> sizes;         // k
  double inertia = 0;              // k-means inertia in PCA space (squared distances of the scores)
  int iterations = 0;
  bool converged = false;          // k-means stopped before its limit: no texel moved, or a settling rule
  std::size_t lastMoved = 0;       // texels its last round moved (> 0: settled, cluster/kmeans.h)
  int reseeded = 0, emptyClusters = 0;
  double explainedVarianceRatio = 0;
  Eigen::VectorXf explainedVariance;  // C: variance of the clustered ABRDFs (x, or space) along each component
  Eigen::Index pcaSampledTexels = 0;  // texels PCA found its subspace on (0: all; cluster/pca.h)
  MatrixXfCol scores;                 // M x C PCA scores when options.keepScores, else empty
  double pcaSeconds = 0, kmeansSeconds = 0, representativeSeconds = 0;
};

// Per-dimension median (or mean) of each cluster's rows of x. k x D. One read of x, column
// slice by column slice; the medians of an 8-bit stack's source from counts of its codes,
// image by image (AbrdfSource::forEachCodedImage), the same bits. progressLabel: a bar in
// dimensions (empty: none).
MatrixXfCol clusterRepresentatives(const AbrdfSource& x, const std::vector<std::int32_t>& ids, int k,
                                   Representative kind, const std::string& progressLabel = "");
MatrixXfCol clusterRepresentatives(const MatrixXfCol& x, const std::vector<std::int32_t>& ids, int k,
                                   Representative kind);

// x: M x D standardized ABRDFs, in memory or streamed from the stack (StackAbrdfSource: the
// same bits; memory: the source's slices, the PCA's (M + D) x (C + p) floats, k-means' M x C
// scores). Reads X 2 * powerIterations + 4 times. `space`: where PCA and k-means look for the
// clusters when not x itself (the same M x D texels in other values, e.g. the linear ABRDFs,
// StackAbrdfSource::linear); the representatives are always x's. Throws nbtf::Error on bad k
// or components, or a space of another shape.
ClusteringResult clusterAbrdfs(const AbrdfSource& x, const ClusteringOptions& options,
                               const AbrdfSource* space = nullptr);
ClusteringResult clusterAbrdfs(const MatrixXfCol& x, const ClusteringOptions& options);

}  // namespace nbtf
