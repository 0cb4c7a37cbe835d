#include "cluster/cluster_edit.h"

#include <string>

#include "cluster/kmeans.h"
#include "util/error.h"

namespace nbtf {

std::vector<int> clusterSizes(const std::vector<std::int32_t>& ids, int k) {
  std::vector<int> sizes(k, 0);
  for (std::size_t t = 0; t < ids.size(); ++t) {
    if (ids[t] < 0 || ids[t] >= k)
      throw Error("cluster edit: texel " + std::to_string(t) + " has cluster id " + std::to_string(ids[t]) +
                  ", expected 0.." + std::to_string(k - 1));
    ++sizes[ids[t]];
  }
  return sizes;
}

bool splitCluster(const MatrixXfCol& scores, std::vector<std::int32_t>& ids, int cluster, int newId,
                  std::uint64_t seed) {
  if (static_cast<Eigen::Index>(ids.size()) != scores.rows())
    throw Error("cluster split: " + std::to_string(ids.size()) + " ids for " + std::to_string(scores.rows()) +
                " score rows");
  std::vector<std::int32_t> members;
  for (std::size_t t = 0; t < ids.size(); ++t)
    if (ids[t] == cluster) members.push_back(static_cast<std::int32_t>(t));
  if (members.size() < 2) return false;
  MatrixXfCol points(static_cast<Eigen::Index>(members.size()), scores.cols());
  for (std::size_t i = 0; i < members.size(); ++i) points.row(i) = scores.row(members[i]);
  bool distinct = false;
  for (std::size_t i = 1; i < members.size() && !distinct; ++i) distinct = points.row(i) != points.row(0);
  if (!distinct) return false;
  KMeansOptions options;
  options.clusters = 2;
  options.seed = seed;
  options.progress = false;
  KMeansResult two = kmeansPlusPlus(points, options);
  if (two.sizes[0] == 0 || two.sizes[1] == 0) return false;
  // The larger child keeps the parent's id; on a tie the first texel's child does.
  const int keep = two.sizes[0] != two.sizes[1] ? (two.sizes[0] > two.sizes[1] ? 0 : 1) : two.ids[0];
  for (std::size_t i = 0; i < members.size(); ++i)
    if (two.ids[i] != keep) ids[members[i]] = newId;
  return true;
}

void mergeClusters(std::vector<std::int32_t>& ids, int from, int into) {
  for (std::int32_t& id : ids)
    if (id == from) id = into;
}

std::vector<int> compactClusters(std::vector<std::int32_t>& ids, int k) {
  std::vector<int> sizes = clusterSizes(ids, k);
  std::vector<int> newOf(k, -1), oldOf;
  for (int c = 0; c < k; ++c)
    if (sizes[c] > 0) newOf[c] = static_cast<int>(oldOf.size()), oldOf.push_back(c);
  for (std::int32_t& id : ids) id = newOf[id];
  return oldOf;
}

}  // namespace nbtf
