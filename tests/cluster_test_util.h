// Helpers shared by the clustering tests: labelled Gaussian blobs and the adjusted Rand
// index (1 = the same partition up to renaming, about 0 = chance agreement), quiet k-means options.
#pragma once
#include <algorithm>
#include <cstdint>
#include <map>
#include <random>
#include <utility>
#include <vector>

#include "cluster/kmeans.h"
#include "preprocess/abrdf_matrix.h"

namespace nbtf::testing {

struct Blobs {
  MatrixXfCol points;
  std::vector<std::int32_t> truth;
};

// `clusters` blobs of `perCluster` points in `dims` dimensions: centres uniform in
// [-spread, spread]^dims, unit-variance Gaussian noise. Rows are shuffled.
inline Blobs makeBlobs(int clusters, int perCluster, int dims, float spread, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-spread, spread);
  std::normal_distribution<float> n(0.0f, 1.0f);
  std::vector<std::vector<float>> centres(clusters, std::vector<float>(dims));
  for (auto& c : centres)
    for (float& v : c) v = u(rng);
  std::vector<int> order(clusters * perCluster);
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  std::shuffle(order.begin(), order.end(), rng);
  Blobs b;
  b.points.resize(order.size(), dims);
  b.truth.resize(order.size());
  for (std::size_t r = 0; r < order.size(); ++r) {
    int cluster = order[r] / perCluster;
    b.truth[r] = cluster;
    for (int d = 0; d < dims; ++d) b.points(r, d) = centres[cluster][d] + n(rng);
  }
  return b;
}

inline double adjustedRandIndex(const std::vector<std::int32_t>& a, const std::vector<std::int32_t>& b) {
  std::map<std::pair<int, int>, long> joint;
  std::map<int, long> rowSum, colSum;
  for (std::size_t i = 0; i < a.size(); ++i) ++joint[{a[i], b[i]}], ++rowSum[a[i]], ++colSum[b[i]];
  auto pairs = [](double n) { return n * (n - 1) / 2; };
  double index = 0, rows = 0, cols = 0;
  for (const auto& [key, n] : joint) index += pairs(n);
  for (const auto& [key, n] : rowSum) rows += pairs(n);
  for (const auto& [key, n] : colSum) cols += pairs(n);
  double expected = rows * cols / pairs(static_cast<double>(a.size()));
  double maximum = 0.5 * (rows + cols);
  return maximum == expected ? 1.0 : (index - expected) / (maximum - expected);
}

// k-means options for k clusters from `seed`, without progress output.
inline KMeansOptions quiet(int k, std::uint64_t seed = 1) {
  KMeansOptions o;
  o.clusters = k;
  o.seed = seed;
  o.progress = false;
  return o;
}

}  // namespace nbtf::testing
