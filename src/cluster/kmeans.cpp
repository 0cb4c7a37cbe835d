// Lloyd iterations with Hamerly's bounds (Hamerly 2010): every point keeps an upper bound
// on the distance to its centre and a lower bound on the distance to every other centre;
// when the centres have moved less than the gap, the point cannot change cluster and is
// skipped. Points that must be rescanned are gathered per block and compared with all
// centres in one matrix product (|x|^2 - 2 x.c + |c|^2).
#include "cluster/kmeans.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>

#include "linalg/blas.h"
#include "cluster/kmeans_internal.h"
#include "util/error.h"
#include "util/parallel.h"
#include "util/progress.h"
#include "util/timer.h"

namespace nbtf {

namespace {


void checkInput(const MatrixXfCol& points, int k) {
  const Eigen::Index m = points.rows();
  if (m == 0 || points.cols() == 0) throw Error("k-means: no points to cluster");
  if (k < 1) throw Error("k-means: the number of clusters must be at least 1, got " + std::to_string(k));
  if (k > m) {
    std::ostringstream s;
    s << "k-means: " << k << " clusters requested, but there are only " << m << " texels";
    throw Error(s.str());
  }
  if (!points.allFinite()) throw Error("k-means: the points contain NaN or Inf values");
}

// The state Lloyd's iterations carry from one round to the next.
struct Lloyd {
  const RowMatrixXf& points;
  RowMatrixXf centers;  // k x C
  std::vector<std::int32_t> assign;
  std::vector<float> upper, lower;  // Hamerly's bounds (distances, not squared)
  std::vector<float> pointNorm2;

  explicit Lloyd(const RowMatrixXf& p) : points(p) {
    const Eigen::Index m = p.rows();
    assign.assign(m, 0);
    upper.assign(m, std::numeric_limits<float>::infinity());
    lower.assign(m, 0.0f);
    pointNorm2.resize(m);
    for (Eigen::Index i = 0; i < m; ++i) pointNorm2[i] = p.row(i).squaredNorm();
  }
  int k() const { return static_cast<int>(centers.rows()); }
  Eigen::Index blocks() const { return (points.rows() + kPointBlock - 1) / kPointBlock; }

  // Moves the centres by `moved` (per centre) and re-assigns every point whose bounds no
  // longer prove its assignment. Returns the number of points that changed cluster.
  std::size_t assignStep(const std::vector<float>& moved, bool everyPoint) {
    const int kk = k();
    const Eigen::Index dims = points.cols();
    // Largest and second largest move: the lower bound of a point drops by the largest
    // move among the centres it is not assigned to.
    int farthest = 0;
    float maxMove = 0, secondMove = 0;
    for (int j = 0; j < kk; ++j) {
      if (moved[j] > maxMove) secondMove = maxMove, maxMove = moved[j], farthest = j;
      else if (moved[j] > secondMove) secondMove = moved[j];
    }
    Eigen::VectorXf centerNorm2 = centers.rowwise().squaredNorm();
    const float largestCenterNorm2 = centerNorm2.maxCoeff();
    std::vector<std::size_t> changedPerBlock(blocks(), 0);
    parallelFor(blocks(), [&](std::size_t blockBegin, std::size_t blockEnd) {
      RowMatrixXf gathered(kPointBlock, dims);
      Eigen::MatrixXf products(kk, kPointBlock);  // one point per column
      Eigen::VectorXf distance2(kk);
      std::vector<std::int32_t> rescan;
      for (std::size_t b = blockBegin; b < blockEnd; ++b) {
        const Eigen::Index begin = b * kPointBlock, end = std::min(points.rows(), begin + kPointBlock);
        rescan.clear();
        for (Eigen::Index i = begin; i < end; ++i) {
          if (everyPoint) {
            rescan.push_back(static_cast<std::int32_t>(i));
            continue;
          }
          const int a = assign[i];
          upper[i] += moved[a];
          lower[i] -= (a == farthest ? secondMove : maxMove);
          if (upper[i] <= lower[i]) continue;
          upper[i] = std::sqrt(squaredDistance(points.row(i).data(), centers.row(a).data(), dims));
          if (upper[i] <= lower[i]) continue;
          rescan.push_back(static_cast<std::int32_t>(i));
        }
        if (rescan.empty()) continue;
        const int rows = static_cast<int>(rescan.size());
        for (int r = 0; r < rows; ++r) gathered.row(r) = points.row(rescan[r]);
        // products = centres (k x C) * gathered^T (C x rows); row-major storage is the
        // transposed column-major one, hence the flags.
        gemmOnThisThread(true, false, kk, rows, static_cast<int>(dims), centers.data(), static_cast<int>(dims),
                         gathered.data(), static_cast<int>(dims), products.data(), kk);
        std::size_t changed = 0;
        for (int r = 0; r < rows; ++r) {
          const std::int32_t i = rescan[r];
          // |x - c|^2 - |x|^2 for every centre; the smallest two, ties to the lower index.
          distance2 = centerNorm2 - 2.0f * products.col(r);
          Eigen::Index bestJ;
          const float best = distance2.minCoeff();
          bestJ = std::find(distance2.data(), distance2.data() + kk, best) - distance2.data();
          distance2[bestJ] = std::numeric_limits<float>::infinity();
          const float second = kk > 1 ? distance2.minCoeff() : std::numeric_limits<float>::infinity();
          // The product form loses digits to cancellation: take the distance to the new
          // centre exactly, and shrink the lower bound by the rounding it may carry.
          if (bestJ != assign[i]) ++changed;
          assign[i] = static_cast<std::int32_t>(bestJ);
          upper[i] = std::sqrt(squaredDistance(points.row(i).data(), centers.row(bestJ).data(), dims));
          float slack = 1e-5f * (pointNorm2[i] + largestCenterNorm2);
          lower[i] = kk == 1 ? std::numeric_limits<float>::infinity()
                             : std::sqrt(std::max(0.0f, second + pointNorm2[i] - slack));
        }
        changedPerBlock[b] = changed;
      }
    });
    return std::accumulate(changedPerBlock.begin(), changedPerBlock.end(), std::size_t(0));
  }

  // Points sorted by cluster (stable): order[offset[j] .. offset[j + 1]) are cluster j's.
  void membership(std::vector<std::int32_t>& order, std::vector<std::int32_t>& offset) const {
    const int kk = k();
    offset.assign(kk + 1, 0);
    for (std::int32_t a : assign) ++offset[a + 1];
    for (int j = 0; j < kk; ++j) offset[j + 1] += offset[j];
    order.resize(assign.size());
    std::vector<std::int32_t> next(offset.begin(), offset.end() - 1);
    for (std::size_t i = 0; i < assign.size(); ++i) order[next[assign[i]]++] = static_cast<std::int32_t>(i);
  }

  // Centres <- means of their points, summed in point order (so the result does not depend
  // on threads). Empty clusters keep their centre. Returns the empty clusters.
  std::vector<int> updateCenters() {
    std::vector<std::int32_t> order, offset;
    membership(order, offset);
    const Eigen::Index dims = points.cols();
    parallelFor(k(), [&](std::size_t begin, std::size_t end) {
      Eigen::VectorXd sum(dims);
      for (std::size_t j = begin; j < end; ++j) {
        if (offset[j] == offset[j + 1]) continue;
        sum.setZero();
        for (std::int32_t p = offset[j]; p < offset[j + 1]; ++p) sum += points.row(order[p]).transpose().cast<double>();
        centers.row(j) = (sum / static_cast<double>(offset[j + 1] - offset[j])).cast<float>().transpose();
      }
    });
    std::vector<int> empty;
    for (int j = 0; j < k(); ++j)
      if (offset[j] == offset[j + 1]) empty.push_back(j);
    return empty;
  }

  // An empty cluster takes the point farthest from its own centre (among clusters that
  // keep at least one point), the point the current centres explain worst. Points that sit
  // exactly on their centre cannot start a new cluster; with fewer distinct points than k
  // some clusters stay empty. Returns the number of clusters re-seeded.
  int reseed(const std::vector<int>& empty) {
    const Eigen::Index m = points.rows(), dims = points.cols();
    std::vector<float> d2(m);
    parallelFor(m, [&](std::size_t begin, std::size_t end) {
      for (std::size_t i = begin; i < end; ++i)
        d2[i] = squaredDistance(points.row(i).data(), centers.row(assign[i]).data(), dims);
    });
    std::vector<std::int32_t> candidates(m);
    std::iota(candidates.begin(), candidates.end(), 0);
    std::stable_sort(candidates.begin(), candidates.end(), [&](std::int32_t a, std::int32_t b) { return d2[a] > d2[b]; });
    std::vector<int> size(k(), 0);
    for (std::int32_t a : assign) ++size[a];
    int reseeded = 0;
    std::size_t next = 0;
    for (int j : empty) {
      while (next < candidates.size() && size[assign[candidates[next]]] < 2) ++next;
      if (next == candidates.size() || d2[candidates[next]] <= 0) break;
      std::int32_t i = candidates[next++];
      --size[assign[i]];
      assign[i] = j;
      ++size[j];
      upper[i] = std::numeric_limits<float>::infinity();  // force a rescan
      lower[i] = 0;
      ++reseeded;
    }
    return reseeded;
  }

  double inertia() const {
    const Eigen::Index dims = points.cols();
    std::vector<double> perBlock(blocks(), 0.0);
    parallelFor(blocks(), [&](std::size_t bBegin, std::size_t bEnd) {
      for (std::size_t b = bBegin; b < bEnd; ++b) {
        const Eigen::Index begin = b * kPointBlock, end = std::min(points.rows(), begin + kPointBlock);
        double sum = 0;
        for (Eigen::Index i = begin; i < end; ++i)
          sum += squaredDistance(points.row(i).data(), centers.row(assign[i]).data(), dims);
        perBlock[b] = sum;
      }
    });
    return std::accumulate(perBlock.begin(), perBlock.end(), 0.0);
  }
};

// The points' variance per coordinate, averaged over the coordinates (in double).
double meanVariance(const RowMatrixXf& points) {
  const Eigen::Index m = points.rows(), dims = points.cols();
  Eigen::RowVectorXd mean = Eigen::RowVectorXd::Zero(dims);
  for (Eigen::Index i = 0; i < m; ++i) mean += points.row(i).cast<double>();
  mean /= static_cast<double>(m);
  double sum = 0;
  for (Eigen::Index i = 0; i < m; ++i) sum += (points.row(i).cast<double>() - mean).squaredNorm();
  return sum / (static_cast<double>(m) * static_cast<double>(dims));
}

KMeansResult runLloyd(const RowMatrixXf& points, RowMatrixXf initialCenters, const KMeansOptions& options,
                      KMeansResult result) {
  if (!(options.settledFraction >= 0 && options.settledFraction < 1))
    throw Error("k-means: the settled fraction must be in [0, 1), got " + std::to_string(options.settledFraction));
  if (!(options.shiftTolerance >= 0 && std::isfinite(options.shiftTolerance)))
    throw Error("k-means: the centre-shift tolerance must be finite and >= 0, got " +
                std::to_string(options.shiftTolerance));
  const auto start = std::chrono::steady_clock::now();
  Lloyd lloyd(points);
  lloyd.centers = std::move(initialCenters);
  const int k = lloyd.k();
  std::vector<float> moved(k, 0.0f);
  lloyd.assignStep(moved, true);

  Progress bar("k-means", options.maxIterations, options.progress);
  const auto settled = static_cast<std::size_t>(options.settledFraction * static_cast<double>(points.rows()));
  const double shiftLimit = settled > 0 ? options.shiftTolerance * meanVariance(points) : -1.0;
  RowMatrixXf previous;
  for (int iteration = 1; iteration <= options.maxIterations; ++iteration) {
    previous = lloyd.centers;
    std::vector<int> empty = lloyd.updateCenters();
    int reseeded = 0;
    if (!empty.empty()) {
      reseeded = lloyd.reseed(empty);
      result.reseeded += reseeded;
      if (reseeded > 0) empty = lloyd.updateCenters();
    }
    double shift = 0;  // squared, summed over the centres
    for (int j = 0; j < k; ++j) {
      moved[j] = (lloyd.centers.row(j) - previous.row(j)).norm();
      shift += static_cast<double>(moved[j]) * moved[j];
    }
    std::size_t changed = lloyd.assignStep(moved, false);
    result.iterations = iteration;
    bar.setStatus("moved " + std::to_string(changed) + " points");
    bar.advance();
    result.lastMoved = changed;
    if ((changed <= settled || shift <= shiftLimit) && reseeded == 0) {
      result.converged = true;
      break;
    }
  }
  bar.setStatus(!result.converged ? "iteration limit reached"
                : result.lastMoved == 0
                    ? "converged after " + std::to_string(result.iterations) + " iterations"
                    : "settled after " + std::to_string(result.iterations) + " iterations (" +
                          std::to_string(result.lastMoved) + " points still moving)");
  if (result.converged) bar.setTotal(static_cast<std::size_t>(result.iterations));
  bar.finish();

  result.ids = lloyd.assign;
  result.centers = lloyd.centers;
  result.sizes.assign(k, 0);
  for (std::int32_t a : lloyd.assign) ++result.sizes[a];
  result.emptyClusters = static_cast<int>(std::count(result.sizes.begin(), result.sizes.end(), 0));
  result.inertia = lloyd.inertia();
  result.lloydSeconds = secondsSince(start);
  return result;
}

}  // namespace

int seedingTrialsFor(int k, int requested) {
  if (requested > 0) return requested;
  return 2 + static_cast<int>(std::log(static_cast<double>(k)));
}

KMeansResult kmeansPlusPlus(const MatrixXfCol& points, const KMeansOptions& options) {
  checkInput(points, options.clusters);
  if (options.maxIterations < 0) throw Error("k-means: maximum iterations must be >= 0");
  const auto start = std::chrono::steady_clock::now();
  RowMatrixXf rows = points;
  Seeding seeding;
  {
    Progress bar("k-means++ seeding", options.clusters, options.progress);
    seeding = kmeansPlusPlusSeeding(rows, options.clusters, seedingTrialsFor(options.clusters, options.seedingTrials),
                                    options.seed, &bar);
    bar.finish();
  }
  KMeansResult result;
  result.seedingSeconds = secondsSince(start);
  return runLloyd(rows, std::move(seeding.centers), options, std::move(result));
}

KMeansResult kmeansFromCenters(const MatrixXfCol& points, const MatrixXfCol& centers, const KMeansOptions& options) {
  checkInput(points, static_cast<int>(centers.rows()));
  if (centers.cols() != points.cols())
    throw Error("k-means: centres have " + std::to_string(centers.cols()) + " coordinates, points " +
                std::to_string(points.cols()));
  if (!centers.allFinite()) throw Error("k-means: the initial centres contain NaN or Inf values");
  RowMatrixXf rows = points;
  return runLloyd(rows, centers, options, KMeansResult());
}

}  // namespace nbtf
