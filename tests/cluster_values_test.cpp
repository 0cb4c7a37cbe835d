#include "cluster/cluster_values.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <Eigen/SVD>

#include "codec/texel_modulation.h"
#include "util/error.h"
#include "util/parallel.h"
#include "model_test_material.h"

namespace nbtf {
namespace {

using testing::makeTestMaterial;

std::vector<int> allImages(int n) {
  std::vector<int> v(n);
  for (int i = 0; i < n; ++i) v[i] = i;
  return v;
}

TEST(ClusterValues, PlainFloorMatchesADirectComputation) {
  auto m = makeTestMaterial();
  ClusterValues cv = clusterValues(m.stack, m.alpha, m.ids, m.clusters, nullptr, 1, true, false);
  EXPECT_NEAR(cv.floorRmse(allImages(m.stack.numImages()), m.stack.numTexels()), testing::clusterFloorRmse(m), 1e-7);
  // The kept means are the per-cluster means.
  const int image = 17, cluster = 2;
  double sum = 0;
  int count = 0;
  for (int t = 0; t < m.stack.numTexels(); ++t)
    if (m.ids[t] == cluster) sum += m.stack.sample(image, t, 1) / m.alpha, ++count;
  EXPECT_NEAR(cv.means[(static_cast<std::size_t>(cluster) * m.stack.numImages() + image) * 3 + 1], sum / count, 1e-6);
}

// The identity training relies on: with orthonormal coefficients e (R terms), the per-texel
// loss of any cluster terms f equals n_c |f - T|^2 + the floor's leftover, checked by brute force.
TEST(ClusterValues, ModulatedTargetsGiveTheExactPerTexelLoss) {
  auto m = makeTestMaterial();
  const int M = m.stack.numTexels(), N = m.stack.numImages();
  std::mt19937 rng(3);
  std::normal_distribution<float> u(1.0f, 0.5f);
  for (int terms : {1, 3}) {
    std::vector<float> raw(static_cast<std::size_t>(M) * terms);
    for (float& x : raw) x = u(rng);
    std::vector<float> e = orthonormalizeTexelCoefficients(raw, terms, m.ids, m.clusters);
    ClusterValues cv = clusterValues(m.stack, m.alpha, m.ids, m.clusters, e.data(), terms, true, false);
    std::vector<int> count(m.clusters, 0);
    for (int id : m.ids) ++count[id];
    const int o = 3 * terms;
    std::normal_distribution<double> normal(0.3, 0.2);
    for (int image : {0, 40, 80}) {
      std::vector<double> f(static_cast<std::size_t>(m.clusters) * o);  // arbitrary terms per cluster
      for (double& x : f) x = normal(rng);
      double brute = 0, viaTargets = cv.withinSse[image];
      for (int t = 0; t < M; ++t)
        for (int c = 0; c < 3; ++c) {
          double model = 0;
          for (int r = 0; r < terms; ++r) model += e[t * terms + r] * f[o * m.ids[t] + 3 * r + c];
          brute += std::pow(model - m.stack.sample(image, t, c) / m.alpha, 2);
        }
      for (int g = 0; g < m.clusters; ++g)
        for (int k = 0; k < o; ++k)
          viaTargets += count[g] * std::pow(f[o * g + k] - cv.means[(static_cast<std::size_t>(g) * N + image) * o + k], 2);
      EXPECT_NEAR(viaTargets, brute, 1e-4 * brute) << "image " << image << " terms " << terms;
    }
  }
}

// The test material is brightness_t x (a profile per class): one coefficient per texel from
// the SVD explains it, so the modulated floor is far below the plain one; more terms never hurt.
TEST(ClusterValues, CoefficientsFromTheDataRemoveThePerTexelBrightness) {
  auto m = makeTestMaterial();
  const int N = m.stack.numImages();
  std::vector<std::uint8_t> use(N, 1);
  const double plain = clusterValues(m.stack, m.alpha, m.ids, m.clusters, nullptr, 1, false, false)
                           .floorRmse(allImages(N), m.stack.numTexels());
  double previous = plain;
  for (int terms : {1, 2, 3}) {
    std::vector<float> a = texelCoefficients(m.stack, m.alpha, m.ids, m.clusters, use, terms, false);
    ASSERT_EQ(a.size(), static_cast<std::size_t>(m.stack.numTexels()) * terms);
    std::vector<float> e = orthonormalizeTexelCoefficients(a, terms, m.ids, m.clusters);
    const double floor = clusterValues(m.stack, m.alpha, m.ids, m.clusters, e.data(), terms, false, false)
                             .floorRmse(allImages(N), m.stack.numTexels());
    EXPECT_LT(floor, 0.05 * plain) << "terms " << terms << ", plain floor " << plain;
    EXPECT_LE(floor, previous * (1 + 1e-6)) << "terms " << terms;
    previous = floor;
    // The first coefficient is a brightness: positive, mean square 1 in each cluster.
    double sq = 0;
    int n = 0;
    for (int t = 0; t < m.stack.numTexels(); ++t)
      if (m.ids[t] == 0) {
        EXPECT_GT(a[t * terms], 0.0f);
        sq += double(a[t * terms]) * a[t * terms];
        ++n;
      }
    EXPECT_NEAR(sq / n, 1.0, 1e-4);
  }
}

// The refit after training: when every texel is exactly a mix of its cluster's terms, the
// least-squares fit gives back the mix.
TEST(ClusterValues, FitRecoversExactMixesOfTheTerms) {
  const int width = 6, height = 5, texels = 30, clusters = 3, terms = 2;
  const auto& h81 = hemisphere81();
  std::vector<Direction> dirs(h81.begin(), h81.begin() + 4);
  BtfStack stack(dirs, dirs, width, height, SampleType::Half);
  const int images = stack.numImages();
  std::vector<std::int32_t> ids(texels);
  for (int t = 0; t < texels; ++t) ids[t] = t % clusters;
  std::mt19937 rng(8);
  std::uniform_real_distribution<float> u(0.1f, 1.0f), w(-0.5f, 1.5f);
  std::vector<float> f(static_cast<std::size_t>(clusters) * images * 3 * terms), mix(texels * terms);
  for (float& x : f) x = u(rng);
  for (float& x : mix) x = w(rng);
  std::vector<float> rgb(3 * texels);
  for (int i = 0; i < images; ++i) {
    for (int t = 0; t < texels; ++t)
      for (int c = 0; c < 3; ++c) {
        float v = 0;
        for (int r = 0; r < terms; ++r) v += mix[t * terms + r] * f[(static_cast<std::size_t>(ids[t]) * images + i) * 6 + 3 * r + c];
        rgb[3 * t + c] = v;
      }
    stack.setImageLinear(i, rgb.data());
  }
  // Every image, in order; alpha 2 (terms are in linear / alpha: scale them).
  std::vector<int> all(images);
  for (int i = 0; i < images; ++i) all[i] = i;
  std::vector<float> scaled(f);
  for (float& x : scaled) x /= 2.0f;
  std::vector<float> fit = fitTexelCoefficients(stack, 2.0f, ids, clusters, all, scaled, terms, false);
  ASSERT_EQ(fit.size(), mix.size());
  // Half-float storage of the stack limits the precision of the values, not the method.
  for (std::size_t j = 0; j < mix.size(); ++j) EXPECT_NEAR(fit[j], mix[j], 2e-3) << j;
  EXPECT_THROW(fitTexelCoefficients(stack, 2.0f, ids, clusters, all, std::vector<float>(5), terms, false), Error);
}

TEST(ClusterValues, CoefficientsUseOnlyTheGivenImagesAndAnyThreadCount) {
  auto m = makeTestMaterial();
  const int N = m.stack.numImages();
  std::vector<std::uint8_t> use(N, 1);
  for (int i = 0; i < N; i += 3) use[i] = 0;
  setThreadCount(1);
  auto one = texelCoefficients(m.stack, m.alpha, m.ids, m.clusters, use, 2, false);
  setThreadCount(2);
  auto two = texelCoefficients(m.stack, m.alpha, m.ids, m.clusters, use, 2, false);
  setThreadCount(0);
  EXPECT_EQ(one, two);
  // Changing a held-out image does not change the coefficients; using it does.
  BtfStack changed = m.stack;
  std::vector<float> rgb(3 * static_cast<std::size_t>(m.stack.numTexels()));
  for (std::size_t j = 0; j < rgb.size(); ++j) rgb[j] = 0.1f + 0.01f * static_cast<float>(j % 17);
  changed.setImageLinear(0, rgb.data());
  EXPECT_EQ(texelCoefficients(changed, m.alpha, m.ids, m.clusters, use, 2, false), one);
  use[0] = 1;
  EXPECT_NE(texelCoefficients(changed, m.alpha, m.ids, m.clusters, use, 2, false), one);
}

// Whichever side of a cluster's ABRDF matrix its SVD is taken from (texels x texels when the
// cluster is smaller than 3 x images, else 3 x images squared), the coefficients are sqrt(n_c)
// times the top left singular vectors: checked against Eigen's SVD of the matrix itself, with
// all 81 images (n_c = 16 < 243) and with 2 images (n_c = 16 > 6).
TEST(ClusterValues, CoefficientsAreTheTopSingularVectorsFromEitherSide) {
  auto m = makeTestMaterial();
  const int N = m.stack.numImages();
  for (int imagesUsed : {N, 2}) {
    std::vector<std::uint8_t> use(N, 0);
    std::vector<int> used;
    for (int i = 0; i < N && static_cast<int>(used.size()) < imagesUsed; i += (imagesUsed == N ? 1 : 40))
      use[i] = 1, used.push_back(i);
    const int terms = 2;
    auto coefficients = texelCoefficients(m.stack, m.alpha, m.ids, m.clusters, use, terms, false);
    for (int g = 0; g < m.clusters; ++g) {
      std::vector<int> members;
      for (int t = 0; t < m.stack.numTexels(); ++t)
        if (m.ids[t] == g) members.push_back(t);
      const int n = static_cast<int>(members.size());
      Eigen::MatrixXd y(n, 3 * static_cast<int>(used.size()));
      for (int k = 0; k < n; ++k)
        for (std::size_t j = 0; j < used.size(); ++j)
          for (int c = 0; c < 3; ++c) y(k, 3 * j + c) = m.stack.sample(used[j], members[k], c) / m.alpha;
      Eigen::JacobiSVD<Eigen::MatrixXd> svd(y, Eigen::ComputeThinU);
      // The first term (well separated from the rest here) exactly; the second, whose singular
      // value lies close to the third on this material, by what defines it: unit mean square
      // and orthogonal to the first.
      Eigen::VectorXd u = svd.matrixU().col(0) * std::sqrt(static_cast<double>(n));
      if (u.sum() < 0) u = -u;
      double square = 0, cross = 0;
      for (int k = 0; k < n; ++k) {
        const std::size_t at = static_cast<std::size_t>(members[k]) * terms;
        EXPECT_NEAR(coefficients[at], u(k), 2e-3) << imagesUsed << " images, cluster " << g << ", texel " << k;
        square += double(coefficients[at + 1]) * coefficients[at + 1];
        cross += double(coefficients[at + 1]) * coefficients[at];
      }
      EXPECT_NEAR(square / n, 1.0, 1e-3) << imagesUsed << " images, cluster " << g;
      EXPECT_NEAR(cross / n, 0.0, 1e-3) << imagesUsed << " images, cluster " << g;
    }
  }
}

}  // namespace
}  // namespace nbtf
