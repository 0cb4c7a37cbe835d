#include "cluster/clustering.h"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <sstream>

#include "util/error.h"
#include "util/parallel.h"
#include "util/progress.h"
#include "util/timer.h"

namespace nbtf {

namespace {

// ---- Selection
//
// Quickselect with a branch-free partition (the comparison result moves the boundary
// instead of choosing a path): random values make std::nth_element's branches mispredict
// about half the time. On return a[0..kth) <= a[kth] <= a[kth+1..n).

template <typename Keep>
int partition(float* a, int lo, int hi, Keep keep) {
  int store = lo;
  for (int i = lo; i < hi; ++i) {
    float x = a[i];
    a[i] = a[store];
    a[store] = x;
    store += keep(x);
  }
  return store;
}

float selectKth(float* a, int n, int kth) {
  int lo = 0, hi = n;
  while (hi - lo > 24) {
    float x = a[lo], y = a[lo + (hi - lo) / 2], z = a[hi - 1];
    float pivot = std::max(std::min(x, y), std::min(std::max(x, y), z));  // median of three
    int split = partition(a, lo, hi, [pivot](float v) { return v < pivot; });
    if (split == lo) {
      // Nothing below the pivot: it is the minimum. Split off the values equal to it, so
      // runs of duplicates (black pixels) always make progress.
      split = partition(a, lo, hi, [pivot](float v) { return v <= pivot; });
      if (kth < split) return pivot;
    }
    if (kth < split) hi = split;
    else lo = split;
  }
  for (int i = lo + 1; i < hi; ++i) {  // insertion sort of the last few
    float v = a[i];
    int j = i;
    for (; j > lo && a[j - 1] > v; --j) a[j] = a[j - 1];
    a[j] = v;
  }
  return a[kth];
}

// The value of rank `rank` (from 0) among a cluster's values, from the counts of its 256 codes.
float rankedCode(const std::uint32_t* counts, std::uint32_t rank, const float* table) {
  std::uint32_t below = 0;
  int code = 0;
  while (below + counts[code] <= rank) below += counts[code++];
  return table[code];
}

// The medians of a source whose values are 256 codes per column (an 8-bit stack): a count of
// each cluster's codes per column, one pass over the bytes, no selection. The tables never fall
// as the code rises, so the value of the middle code is the middle value, and the mean of the
// two middle ones is the same float arithmetic on the same floats: bit for bit the selection's
// result. Returns false for other sources.
bool medianCodes(const AbrdfSource& x, const std::vector<std::int32_t>& ids, const std::vector<std::int32_t>& offset,
                 MatrixXfCol& out, const std::string& progressLabel) {
  const int k = static_cast<int>(offset.size()) - 1;
  std::vector<std::vector<std::uint32_t>> counts(threadCount());  // per worker: k x 256, zero between columns
  return x.forEachCodedImage([&](Eigen::Index image, const std::uint8_t* bytes, const float* tables, int worker) {
    std::vector<std::uint32_t>& count = counts[static_cast<std::size_t>(worker)];
    if (count.empty()) count.assign(static_cast<std::size_t>(k) * 256, 0);
    for (int c = 0; c < 3; ++c) {
      for (std::size_t t = 0; t < ids.size(); ++t) ++count[static_cast<std::size_t>(ids[t]) * 256 + bytes[3 * t + c]];
      float* rep = out.col(3 * image + c).data();
      const float* table = tables + 256 * c;
      for (int g = 0; g < k; ++g) {
        const std::uint32_t n = static_cast<std::uint32_t>(offset[g + 1] - offset[g]);
        std::uint32_t* cluster = &count[static_cast<std::size_t>(g) * 256];
        if (n == 0) {
          rep[g] = 0.0f;  // as the selection gives an empty cluster
        } else {
          const float upperMiddle = rankedCode(cluster, n / 2, table);
          rep[g] = n % 2 == 1 ? upperMiddle : 0.5f * (rankedCode(cluster, n / 2 - 1, table) + upperMiddle);
        }
        std::fill(cluster, cluster + 256, 0u);
      }
    }
  }, progressLabel);
}

}  // namespace

// ---- Representatives

MatrixXfCol clusterRepresentatives(const MatrixXfCol& x, const std::vector<std::int32_t>& ids, int k,
                                   Representative kind) {
  return clusterRepresentatives(DenseAbrdfSource(x), ids, k, kind);
}

MatrixXfCol clusterRepresentatives(const AbrdfSource& x, const std::vector<std::int32_t>& ids, int k,
                                   Representative kind, const std::string& progressLabel) {
  if (k < 1) throw Error("cluster representatives: k must be at least 1, got " + std::to_string(k));
  if (static_cast<Eigen::Index>(ids.size()) != x.rows()) {
    std::ostringstream s;
    s << "cluster representatives: " << ids.size() << " ids for " << x.rows() << " ABRDFs";
    throw Error(s.str());
  }
  // Texels sorted by cluster (counting sort), so each cluster is one run of indices.
  std::vector<std::int32_t> offset(k + 1, 0), order(ids.size());
  for (std::size_t t = 0; t < ids.size(); ++t) {
    if (ids[t] < 0 || ids[t] >= k) {
      std::ostringstream s;
      s << "cluster representatives: texel " << t << " has cluster id " << ids[t] << ", expected 0.." << k - 1;
      throw Error(s.str());
    }
    ++offset[ids[t] + 1];
  }
  for (int c = 0; c < k; ++c) offset[c + 1] += offset[c];
  {
    std::vector<std::int32_t> next(offset.begin(), offset.end() - 1);
    for (std::size_t t = 0; t < ids.size(); ++t) order[next[ids[t]]++] = static_cast<std::int32_t>(t);
  }
  std::int32_t largest = 0;
  for (int c = 0; c < k; ++c) largest = std::max(largest, offset[c + 1] - offset[c]);

  MatrixXfCol out(k, x.cols());
  if (kind == Representative::Median && medianCodes(x, ids, offset, out, progressLabel)) return out;

  // Dimension by dimension: a column of X is contiguous and small enough to stay in cache
  // while every cluster gathers its values from it, and no cluster is ever copied whole
  // (a single cluster of a full material would be gigabytes). Columns come in slices
  // (preprocess/abrdf_source.h): from the stack, X never exists whole either.
  const Eigen::Index rows = x.rows();
  x.forEachColumnSlice([&](Eigen::Index c0, Eigen::Index c1, const float* data) {
    std::vector<float> values(largest);
    for (Eigen::Index d = c0; d < c1; ++d) {
      const float* column = data + (d - c0) * rows;
      float* rep = out.col(d).data();
      for (int c = 0; c < k; ++c) {
        const std::int32_t n = offset[c + 1] - offset[c];
        const std::int32_t* members = order.data() + offset[c];
        if (n == 0) {
          rep[c] = 0.0f;  // an empty cluster (no texel refers to it): the standardized mean
          continue;
        }
        if (kind == Representative::Mean) {
          double sum = 0;
          for (std::int32_t i = 0; i < n; ++i) sum += column[members[i]];
          rep[c] = static_cast<float>(sum / n);
          continue;
        }
        for (std::int32_t i = 0; i < n; ++i) values[i] = column[members[i]];
        // Median; for an even count the mean of the two middle values (numpy's convention).
        float upperMiddle = selectKth(values.data(), n, n / 2);
        if (n % 2 == 1) {
          rep[c] = upperMiddle;
        } else {
          float lowerMiddle = *std::max_element(values.data(), values.data() + n / 2);
          rep[c] = 0.5f * (lowerMiddle + upperMiddle);
        }
      }
    }
  }, progressLabel);
  return out;
}

// ---- The stage

const char* clusteringSpaceName(ClusteringSpace space) { return space == ClusteringSpace::Linear ? "linear" : "log"; }

std::unique_ptr<StackAbrdfSource> clusteringSpaceSource(const BtfStack& stack, ClusteringSpace space, float alpha) {
  if (space == ClusteringSpace::Log) return nullptr;
  return std::make_unique<StackAbrdfSource>(StackAbrdfSource::linear(stack, alpha));
}

ClusteringSpace parseClusteringSpace(const std::string& text, const std::string& where) {
  if (text == "log") return ClusteringSpace::Log;
  if (text == "linear") return ClusteringSpace::Linear;
  throw Error(where + ": expected log or linear, got '" + text + "'");
}

ClusteringResult clusterAbrdfs(const MatrixXfCol& x, const ClusteringOptions& options) {
  return clusterAbrdfs(DenseAbrdfSource(x), options);
}

ClusteringResult clusterAbrdfs(const AbrdfSource& x, const ClusteringOptions& options, const AbrdfSource* space) {
  const Eigen::Index m = x.rows(), dims = x.cols();
  if (space && (space->rows() != m || space->cols() != dims)) {
    std::ostringstream s;
    s << "clustering: the clustering space is " << space->rows() << " x " << space->cols() << ", the ABRDFs " << m
      << " x " << dims;
    throw Error(s.str());
  }
  if (m == 0 || dims == 0) throw Error("clustering: empty ABRDF matrix");
  if (options.clusters < 1)
    throw Error("clustering: the number of clusters must be at least 1, got " + std::to_string(options.clusters));
  if (options.clusters > m) {
    std::ostringstream s;
    s << "clustering: " << options.clusters << " clusters requested, but there are only " << m << " texels";
    throw Error(s.str());
  }
  ClusteringResult result;

  auto start = std::chrono::steady_clock::now();
  PcaOptions pcaOptions = options.pca;
  pcaOptions.seed = options.seed;
  pcaOptions.progress = options.progress;
  PcaResult pca = randomizedPca(space ? *space : x, pcaOptions);
  result.pcaSeconds = secondsSince(start);
  result.explainedVariance = pca.explainedVariance;
  result.explainedVarianceRatio = pca.explainedRatio();
  result.pcaSampledTexels = pca.sampledTexels;

  start = std::chrono::steady_clock::now();
  KMeansOptions kmeansOptions = options.kmeans;
  kmeansOptions.clusters = options.clusters;
  kmeansOptions.seed = options.seed;
  kmeansOptions.progress = options.progress;
  KMeansResult kmeans = kmeansPlusPlus(pca.scores, kmeansOptions);
  result.kmeansSeconds = secondsSince(start);
  result.inertia = kmeans.inertia;
  result.iterations = kmeans.iterations;
  result.converged = kmeans.converged;
  result.lastMoved = kmeans.lastMoved;
  result.reseeded = kmeans.reseeded;
  result.emptyClusters = kmeans.emptyClusters;

  start = std::chrono::steady_clock::now();
  result.representatives = clusterRepresentatives(x, kmeans.ids, options.clusters, options.representative,
                                                  options.progress ? "representatives (dimensions)" : "");
  result.representativeSeconds = secondsSince(start);
  result.ids = std::move(kmeans.ids);
  result.sizes = std::move(kmeans.sizes);
  if (options.keepScores) result.scores = std::move(pca.scores);
  return result;
}

}  // namespace nbtf
