// k-means++ seeding (Arthur and Vassilvitskii 2007; section 3.2 of the clustered neural
// BTF): each new centre is a point drawn with probability proportional to D(x)^2, its
// squared distance to the closest centre chosen so far.
#include <algorithm>
#include <cmath>

#include "linalg/blas.h"
#include "cluster/kmeans_internal.h"
#include "util/random.h"
#include "util/parallel.h"
#include "util/progress.h"

namespace nbtf {

namespace {

// D(x)^2 kept with per-block sums, so a draw costs O(M / block + block) and the total is
// always summed in the same order.
class PotentialSampler {
 public:
  explicit PotentialSampler(const std::vector<float>& distance2) : d2_(distance2) {
    const Eigen::Index m = static_cast<Eigen::Index>(d2_.size());
    blockSums_.assign((m + kPointBlock - 1) / kPointBlock, 0.0);
    for (std::size_t b = 0; b < blockSums_.size(); ++b) refreshBlock(b);
  }
  void refreshBlock(std::size_t b) {
    std::size_t begin = b * kPointBlock, end = std::min(d2_.size(), begin + kPointBlock);
    double sum = 0;
    for (std::size_t i = begin; i < end; ++i) sum += d2_[i];
    blockSums_[b] = sum;
  }
  double total() const {
    double sum = 0;
    for (double s : blockSums_) sum += s;
    return sum;
  }
  // A point drawn with probability d2 / total (uniformly when every d2 is 0).
  std::int32_t draw(StageRandom& random) const {
    const double sum = total();
    if (!(sum > 0)) return static_cast<std::int32_t>(random.below(d2_.size()));
    double target = random.uniform() * sum;
    std::size_t b = 0;
    for (; b + 1 < blockSums_.size() && target >= blockSums_[b]; ++b) target -= blockSums_[b];
    std::size_t begin = b * kPointBlock, end = std::min(d2_.size(), begin + kPointBlock);
    std::size_t last = begin;
    for (std::size_t i = begin; i < end; ++i) {
      if (d2_[i] <= 0) continue;
      last = i;
      if (target < d2_[i]) return static_cast<std::int32_t>(i);
      target -= d2_[i];
    }
    return static_cast<std::int32_t>(last);  // rounding ran past the end: the last positive point
  }

 private:
  const std::vector<float>& d2_;
  std::vector<double> blockSums_;
};

// What adding one candidate centre would change: the points it would take over.
struct CandidateEffect {
  std::int32_t point = -1;
  double potentialChange = 0;  // <= 0
  std::vector<std::pair<std::int32_t, float>> takenOver;  // (point, new squared distance)
};

// Points grouped by their closest centre, with the group's radius (largest distance):
// a candidate c can take no point of group j when |c - centre_j| >= 2 * radius_j.
struct CentreGroups {
  std::vector<std::vector<std::int32_t>> members;
  std::vector<float> radius;
  Eigen::VectorXf norm2;     // |centre_j|^2
  std::vector<char> shrunk;  // lost points to the newest centre
  explicit CentreGroups(int k) : members(k), radius(k, 0.0f), norm2(k), shrunk(k, 0) {}
};

// The first centre, drawn uniformly; every point starts in its group.
void seedFirstCentre(const RowMatrixXf& points, StageRandom& random, Seeding& s, CentreGroups& groups) {
  const Eigen::Index m = points.rows(), dims = points.cols();
  std::int32_t first = static_cast<std::int32_t>(random.below(m));
  s.centers.row(0) = points.row(first);
  parallelFor(m, [&](std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i)
      s.distance2[i] = squaredDistance(points.row(i).data(), s.centers.row(0).data(), dims);
  });
  groups.members[0].resize(m);
  for (Eigen::Index i = 0; i < m; ++i) groups.members[0][i] = static_cast<std::int32_t>(i);
  groups.radius[0] = std::sqrt(*std::max_element(s.distance2.begin(), s.distance2.end()));
}

// Groups within reach of each candidate: |c - centre_j|^2 < 4 radius_j^2, with `products`
// (n x trials) holding centre . candidate. The product form of the distance carries
// rounding, so only skip with a margin. Returns the points in reach, over all candidates.
std::size_t findReach(const RowMatrixXf& candidates, const Eigen::MatrixXf& products, const CentreGroups& groups,
                      int n, std::vector<std::vector<int>>& reach) {
  std::size_t work = 0;
  for (int t = 0; t < static_cast<int>(reach.size()); ++t) {
    const float candidateNorm2 = candidates.row(t).squaredNorm();
    reach[t].clear();
    for (int j = 0; j < n; ++j) {
      float centre2 = groups.norm2[j] + candidateNorm2 - 2.0f * products(j, t);
      float margin = 1e-5f * (groups.norm2[j] + candidateNorm2);
      if (centre2 - margin < 4.0f * groups.radius[j] * groups.radius[j])
        reach[t].push_back(j), work += groups.members[j].size();
    }
  }
  return work;
}

// The points candidate `c` would take over from the groups in its reach.
void evaluateCandidate(const RowMatrixXf& points, const float* c, const std::vector<int>& reach,
                       const CentreGroups& groups, const std::vector<float>& distance2, CandidateEffect& e) {
  const Eigen::Index dims = points.cols();
  e.potentialChange = 0;
  e.takenOver.clear();
  for (int j : reach)
    for (std::int32_t i : groups.members[j]) {
      float d2 = squaredDistance(points.row(i).data(), c, dims);
      if (d2 < distance2[i]) {
        e.potentialChange += static_cast<double>(d2) - distance2[i];
        e.takenOver.emplace_back(i, d2);
      }
    }
}

// Makes the chosen candidate centre n: moves the points it takes over into its group, shrinks
// the groups they left, and marks the sampler's blocks whose D(x)^2 changed.
void commitCentre(const RowMatrixXf& points, const CandidateEffect& chosen, int n, Seeding& s, CentreGroups& groups,
                  std::vector<char>& touchedBlock) {
  s.centers.row(n) = points.row(chosen.point);
  groups.norm2[n] = s.centers.row(n).squaredNorm();
  float newRadius2 = 0;
  for (const auto& [i, d2] : chosen.takenOver) {
    groups.shrunk[s.nearest[i]] = 1;
    s.nearest[i] = n;
    s.distance2[i] = d2;
    groups.members[n].push_back(i);
    newRadius2 = std::max(newRadius2, d2);
    touchedBlock[i / kPointBlock] = 1;
  }
  groups.radius[n] = std::sqrt(newRadius2);
  for (int j = 0; j < n; ++j) {
    if (!groups.shrunk[j]) continue;
    groups.shrunk[j] = 0;
    auto& list = groups.members[j];
    list.erase(std::remove_if(list.begin(), list.end(), [&](std::int32_t i) { return s.nearest[i] != j; }),
               list.end());
    float r2 = 0;
    for (std::int32_t i : list) r2 = std::max(r2, s.distance2[i]);
    groups.radius[j] = std::sqrt(r2);
  }
}

}  // namespace

Seeding kmeansPlusPlusSeeding(const RowMatrixXf& points, int k, int trials, std::uint64_t seed,
                              Progress* progress) {
  const Eigen::Index m = points.rows(), dims = points.cols();
  StageRandom random(seed);
  Seeding s;
  s.centers.resize(k, dims);
  s.nearest.assign(m, 0);
  s.distance2.assign(m, 0.0f);
  CentreGroups groups(k);
  seedFirstCentre(points, random, s, groups);
  PotentialSampler sampler(s.distance2);
  if (progress) progress->advance();

  std::vector<CandidateEffect> effects(trials);
  std::vector<std::vector<int>> reach(trials);  // per candidate: the groups it may take points from
  groups.norm2[0] = s.centers.row(0).squaredNorm();
  RowMatrixXf candidates(trials, dims);
  Eigen::MatrixXf products;  // n x trials: centre . candidate
  std::vector<char> touchedBlock((m + kPointBlock - 1) / kPointBlock, 0);
  for (int n = 1; n < k; ++n) {
    for (int t = 0; t < trials; ++t) {
      effects[t].point = sampler.draw(random);
      candidates.row(t) = points.row(effects[t].point);
    }
    // products = centres (n x C) * candidates^T; row-major storage, hence the flags.
    products.resize(n, trials);
    gemmOnThisThread(true, false, n, trials, static_cast<int>(dims), s.centers.data(), static_cast<int>(dims),
                     candidates.data(), static_cast<int>(dims), products.data(), n);
    const std::size_t work = findReach(candidates, products, groups, n, reach);
    // Each candidate is scanned by one thread, so results do not depend on the thread
    // count; threads are only started when the scan outweighs starting them.
    auto evaluate = [&](std::size_t t) {
      evaluateCandidate(points, candidates.row(t).data(), reach[t], groups, s.distance2, effects[t]);
    };
    if (work < 32768 || threadCount() == 1) {
      for (int t = 0; t < trials; ++t) evaluate(t);
    } else {
      parallelForDynamic(trials, [&](std::size_t t, int) { evaluate(t); });
    }
    int best = 0;
    for (int t = 1; t < trials; ++t)
      if (effects[t].potentialChange < effects[best].potentialChange) best = t;
    commitCentre(points, effects[best], n, s, groups, touchedBlock);
    for (std::size_t b = 0; b < touchedBlock.size(); ++b)
      if (touchedBlock[b]) sampler.refreshBlock(b), touchedBlock[b] = 0;
    if (progress) progress->advance();
  }
  return s;
}

}  // namespace nbtf
