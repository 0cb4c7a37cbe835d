// Editing a clustering between training stages (adaptive clustering, pipeline/adaptive.h):
// split a cluster in two, merge one into another, drop the empty ones. Pure functions of the
// ids (and the texels' PCA scores for a split); deterministic for a seed.
#pragma once
#include <cstdint>
#include <vector>

#include "preprocess/abrdf_matrix.h"

namespace nbtf {

// Splits `cluster` by 2-means (k-means++ seeding, then Lloyd) on its texels' rows of
// `scores` (M x C, the PCA space the clustering was made in). The larger child keeps the id
// `cluster` (on a tie, the child of the first texel), the other's texels get `newId`.
// Returns false and leaves `ids` alone when the cluster has fewer than two distinct points.
bool splitCluster(const MatrixXfCol& scores, std::vector<std::int32_t>& ids, int cluster, int newId,
                  std::uint64_t seed);

// Every texel of cluster `from` joins cluster `into` (`from` is left empty).
void mergeClusters(std::vector<std::int32_t>& ids, int from, int into);

// Drops the empty clusters of ids in 0..k-1 and renumbers the others 0..k'-1 in their order.
// Returns, for each new id, its old id (k' entries).
std::vector<int> compactClusters(std::vector<std::int32_t>& ids, int k);

// Texels per cluster (k entries; throws nbtf::Error on an id outside 0..k-1).
std::vector<int> clusterSizes(const std::vector<std::int32_t>& ids, int k);

}  // namespace nbtf
