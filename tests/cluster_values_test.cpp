#include "cluster/cluster_values.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include <Eigen/Eigenvalues>
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

// A small half-float stack of the first `directions` measured directions as lights and views
// (values set by the test), and ids that deal the texels to the clusters in turn.
BtfStack tinyStack(int width, int height, int directions) {
  const auto& h81 = hemisphere81();
  std::vector<Direction> dirs(h81.begin(), h81.begin() + directions);
  return BtfStack(dirs, dirs, width, height, SampleType::Half);
}
std::vector<std::int32_t> roundRobinIds(int texels, int clusters) {
  std::vector<std::int32_t> ids(texels);
  for (int t = 0; t < texels; ++t) ids[t] = t % clusters;
  return ids;
}
// Per-cluster values written cluster by cluster (clusters x images x width), rearranged image by
// image (images x clusters x width) as fitTexelCoefficients takes them.
std::vector<float> imageMajor(const std::vector<float>& byCluster, int clusters, int images, int width) {
  std::vector<float> out(byCluster.size());
  for (int g = 0; g < clusters; ++g)
    for (int i = 0; i < images; ++i)
      for (int j = 0; j < width; ++j)
        out[(static_cast<std::size_t>(i) * clusters + g) * width + j] =
            byCluster[(static_cast<std::size_t>(g) * images + i) * width + j];
  return out;
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

// The plain floor from the modulated pass (plainFloorToo: both fits side by side in one pass
// over each image) is the plain pass's, bit for bit, and leaves the modulated values as they were.
TEST(ClusterValues, PlainFloorBesideTheModulatedOneIsThePlainPasses) {
  auto m = makeTestMaterial();
  std::vector<float> raw(static_cast<std::size_t>(m.stack.numTexels()) * 3);
  std::mt19937 rng(5);
  std::normal_distribution<float> u(1.0f, 0.5f);
  for (float& x : raw) x = u(rng);
  std::vector<float> e = orthonormalizeTexelCoefficients(raw, 1, m.ids, m.clusters, 3);
  ClusterValues plain = clusterValues(m.stack, m.alpha, m.ids, m.clusters, nullptr, 1, false, false);
  ClusterValues alone = clusterValues(m.stack, m.alpha, m.ids, m.clusters, e.data(), 1, true, false, 3);
  ClusterValues both = clusterValues(m.stack, m.alpha, m.ids, m.clusters, e.data(), 1, true, false, 3, true);
  EXPECT_TRUE(alone.plainWithinSse.empty());
  ASSERT_EQ(both.plainWithinSse.size(), plain.withinSse.size());
  EXPECT_EQ(both.plainWithinSse, plain.withinSse);
  EXPECT_EQ(both.withinSse, alone.withinSse);
  EXPECT_EQ(both.means, alone.means);
  const std::vector<int> images = allImages(m.stack.numImages());
  EXPECT_EQ(both.plainFloorRmse(images, m.stack.numTexels()), plain.floorRmse(images, m.stack.numTexels()));
  EXPECT_NE(both.plainFloorRmse(images, m.stack.numTexels()), both.floorRmse(images, m.stack.numTexels()));
}

// The identity training relies on: with orthonormal coefficients e (R terms), the per-texel
// loss of any cluster terms f equals n_c |f - T|^2 + the floor's leftover, checked by brute force.
TEST(ClusterValues, ModulatedTargetsGiveTheExactPerTexelLoss) {
  auto m = makeTestMaterial();
  const int M = m.stack.numTexels(), N = m.stack.numImages();
  std::mt19937 rng(3);
  std::normal_distribution<float> u(1.0f, 0.5f);
  // (terms, channels): one coefficient per term, or one per term and channel (format 1.5).
  for (auto [terms, channels] : {std::pair{1, 1}, std::pair{3, 1}, std::pair{1, 3}, std::pair{2, 3}}) {
    const int columns = terms * channels;
    std::vector<float> raw(static_cast<std::size_t>(M) * columns);
    for (float& x : raw) x = u(rng);
    std::vector<float> e = orthonormalizeTexelCoefficients(raw, terms, m.ids, m.clusters, channels);
    ClusterValues cv = clusterValues(m.stack, m.alpha, m.ids, m.clusters, e.data(), terms, true, false, channels);
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
          for (int r = 0; r < terms; ++r)
            model += e[t * columns + r * channels + (channels > 1 ? c : 0)] * f[o * m.ids[t] + 3 * r + c];
          brute += std::pow(model - m.stack.sample(image, t, c) / m.alpha, 2);
        }
      for (int g = 0; g < m.clusters; ++g)
        for (int k = 0; k < o; ++k)
          viaTargets += count[g] * std::pow(f[o * g + k] - cv.means[(static_cast<std::size_t>(g) * N + image) * o + k], 2);
      EXPECT_NEAR(viaTargets, brute, 1e-4 * brute) << "image " << image << " terms " << terms << " channels "
                                                    << channels;
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
  BtfStack stack = tinyStack(width, height, 4);
  const int images = stack.numImages();
  const std::vector<std::int32_t> ids = roundRobinIds(texels, clusters);
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
  std::vector<float> fit = fitTexelCoefficients(stack, 2.0f, ids, clusters, all, imageMajor(scaled, clusters, images, 3 * terms), terms, false);
  ASSERT_EQ(fit.size(), mix.size());
  // Half-float storage of the stack limits the precision of the values, not the method.
  for (std::size_t j = 0; j < mix.size(); ++j) EXPECT_NEAR(fit[j], mix[j], 2e-3) << j;
  EXPECT_THROW(fitTexelCoefficients(stack, 2.0f, ids, clusters, all, std::vector<float>(5), terms, false), Error);
}

// A material whose texels are their cluster's profile times a colour of their own (r, g, b
// factors that differ): one brightness factor per texel cannot explain it; one factor per
// channel (channels 3) can, from the data's SVD, and the refit gives back the colours.
TEST(ClusterValues, PerChannelCoefficientsRemoveThePerTexelColour) {
  const int width = 6, height = 5, texels = 30, clusters = 3;
  BtfStack stack = tinyStack(width, height, 4);
  const int images = stack.numImages();
  const std::vector<std::int32_t> ids = roundRobinIds(texels, clusters);
  std::mt19937 rng(12);
  std::uniform_real_distribution<float> u(0.2f, 1.0f), colour(0.5f, 1.5f);
  std::vector<float> profile(static_cast<std::size_t>(clusters) * images * 3), tint(3 * texels);
  for (float& x : profile) x = u(rng);
  for (float& x : tint) x = colour(rng);
  std::vector<float> rgb(3 * texels);
  for (int i = 0; i < images; ++i) {
    for (int t = 0; t < texels; ++t)
      for (int c = 0; c < 3; ++c) rgb[3 * t + c] = tint[3 * t + c] * profile[(static_cast<std::size_t>(ids[t]) * images + i) * 3 + c];
    stack.setImageLinear(i, rgb.data());
  }
  const std::vector<std::uint8_t> use(images, 1);
  auto floorOf = [&](int channels) {
    std::vector<float> a = texelCoefficients(stack, 1.0f, ids, clusters, use, 1, false, channels);
    EXPECT_EQ(a.size(), static_cast<std::size_t>(texels) * channels);
    std::vector<float> e = orthonormalizeTexelCoefficients(a, 1, ids, clusters, channels);
    return clusterValues(stack, 1.0f, ids, clusters, e.data(), 1, false, false, channels)
        .floorRmse(allImages(images), texels);
  };
  const double plain = clusterValues(stack, 1.0f, ids, clusters, nullptr, 1, false, false).floorRmse(allImages(images), texels);
  const double shared = floorOf(1), perChannel = floorOf(3);
  EXPECT_LT(shared, plain);
  EXPECT_GT(shared, 0.02 * plain) << "a brightness factor alone cannot explain a per-texel colour";
  EXPECT_LT(perChannel, 2e-3 * plain) << "(half-float storage of the stack is all that is left)";
  // The refit per channel to the cluster profiles gives each texel's colour back.
  std::vector<float> fit = fitTexelCoefficients(stack, 1.0f, ids, clusters, allImages(images), imageMajor(profile, clusters, images, 3), 1, false, 0, 3);
  ASSERT_EQ(fit.size(), tint.size());
  for (std::size_t j = 0; j < tint.size(); ++j) EXPECT_NEAR(fit[j], tint[j], 2e-3) << j;
  // A large mean weight keeps every texel's per-channel mean over the images (its colour in
  // the mean brightness map) whatever the terms: here terms that are not the profiles.
  std::vector<float> wrong(profile);
  for (std::size_t j = 0; j < wrong.size(); ++j) wrong[j] *= 0.5f + static_cast<float>(j % 5) * 0.25f;
  std::vector<float> kept = fitTexelCoefficients(stack, 1.0f, ids, clusters, allImages(images), imageMajor(wrong, clusters, images, 3), 1, false, 1e6, 3);
  for (int t = 0; t < texels; ++t)
    for (int c = 0; c < 3; ++c) {
      double decoded = 0, data = 0;
      for (int i = 0; i < images; ++i) {
        decoded += kept[3 * t + c] * wrong[(static_cast<std::size_t>(ids[t]) * images + i) * 3 + c];
        data += stack.sample(i, t, c);
      }
      EXPECT_NEAR(decoded / images, data / images, 1e-4 * (data / images)) << "texel " << t << " channel " << c;
    }
}

// The mean-weighted refit: one term, e = (<f, y> + w n F.Y) / (<f, f> + w n F.F) with F, Y
// the per-channel means over the images (brute force here); w = 0 is plain least squares,
// and a larger w brings every texel's mean closer to its data's.
TEST(ClusterValues, MeanWeightedFitMatchesTheClosedFormAndKeepsTexelMeans) {
  const int width = 4, height = 3, texels = 12, clusters = 2;
  BtfStack stack = tinyStack(width, height, 3);
  const int images = stack.numImages();
  const std::vector<std::int32_t> ids = roundRobinIds(texels, clusters);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.1f, 1.0f);
  std::vector<float> f(static_cast<std::size_t>(clusters) * images * 3), y(static_cast<std::size_t>(texels) * images * 3);
  for (float& x : f) x = u(rng);
  for (float& x : y) x = u(rng);  // not a multiple of the term: the fit leaves a residual
  std::vector<float> rgb(3 * texels);
  for (int i = 0; i < images; ++i) {
    for (int t = 0; t < texels; ++t)
      for (int c = 0; c < 3; ++c) rgb[3 * t + c] = y[(static_cast<std::size_t>(t) * images + i) * 3 + c];
    stack.setImageLinear(i, rgb.data());
    stack.imageLinear(i, rgb.data());  // the stored (half-rounded) values are the data
    for (int t = 0; t < texels; ++t)
      for (int c = 0; c < 3; ++c) y[(static_cast<std::size_t>(t) * images + i) * 3 + c] = rgb[3 * t + c];
  }
  std::vector<int> all(images);
  for (int i = 0; i < images; ++i) all[i] = i;
  auto meanError = [&](const std::vector<float>& e) {
    double sse = 0;
    for (int t = 0; t < texels; ++t)
      for (int c = 0; c < 3; ++c) {
        double d = 0;
        for (int i = 0; i < images; ++i)
          d += e[t] * f[(static_cast<std::size_t>(ids[t]) * images + i) * 3 + c] - y[(static_cast<std::size_t>(t) * images + i) * 3 + c];
        sse += d * d;
      }
    return sse;
  };
  double previous = std::numeric_limits<double>::infinity();
  for (double w : {0.0, 1.0, 100.0}) {
    std::vector<float> fit = fitTexelCoefficients(stack, 1.0f, ids, clusters, all, imageMajor(f, clusters, images, 3), 1, false, w);
    for (int t = 0; t < texels; ++t) {
      double fy = 0, ff = 0, F[3] = {0, 0, 0}, Y[3] = {0, 0, 0};
      for (int i = 0; i < images; ++i)
        for (int c = 0; c < 3; ++c) {
          const double fv = f[(static_cast<std::size_t>(ids[t]) * images + i) * 3 + c];
          const double yv = y[(static_cast<std::size_t>(t) * images + i) * 3 + c];
          fy += fv * yv, ff += fv * fv, F[c] += fv / images, Y[c] += yv / images;
        }
      double num = fy, den = ff;
      for (int c = 0; c < 3; ++c) num += w * images * F[c] * Y[c], den += w * images * F[c] * F[c];
      EXPECT_NEAR(fit[t], num / den, 1e-5) << "w " << w << " texel " << t;
    }
    const double err = meanError(fit);
    EXPECT_LT(err, previous) << "w " << w;
    previous = err;
  }
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

// Many clusters take several batches (a batch holds threads x 8 x the mean cluster size texels'
// worth of floats, in the stack's sample bytes): each cluster's coefficients are still its own,
// whichever batch and place it is gathered in (here the clusters renumbered back to front).
TEST(ClusterValues, CoefficientsDoNotDependOnTheBatchAClusterIsIn) {
  for (SampleType type : {SampleType::Srgb8, SampleType::Half}) {
    const auto& h81 = hemisphere81();
    std::vector<Direction> dirs(h81.begin(), h81.begin() + 3);
    BtfStack stack(dirs, dirs, 24, 20, type);
    std::mt19937 random(7);
    std::uniform_real_distribution<float> value(0.02f, 0.9f);
    std::vector<float> rgb(3 * static_cast<std::size_t>(stack.numTexels()));
    for (int i = 0; i < stack.numImages(); ++i) {
      for (float& v : rgb) v = value(random);
      stack.setImageLinear(i, rgb.data());
    }
    const int clusters = 120;  // 4 texels each on average, sizes 1 to 8
    std::vector<std::int32_t> ids(stack.numTexels()), renumbered(ids.size());
    for (int t = 0; t < stack.numTexels(); ++t) {
      ids[t] = static_cast<std::int32_t>((t * t + 3 * t) % clusters);
      renumbered[t] = clusters - 1 - ids[t];
    }
    const std::vector<std::uint8_t> use(stack.numImages(), 1);
    const float alpha = 0.9f;
    const auto a = texelCoefficients(stack, alpha, ids, clusters, use, 1, false, 3);
    const auto b = texelCoefficients(stack, alpha, renumbered, clusters, use, 1, false, 3);
    ASSERT_EQ(a.size(), 3u * stack.numTexels());
    EXPECT_EQ(a, b);
    double square = 0;  // unit mean square per channel and cluster: not all zero
    for (float c : a) square += double(c) * c;
    EXPECT_NEAR(square / a.size(), 1.0, 1e-3);
  }
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

// Subspace iteration against the exact SVD (from the small side's eigen-decomposition, in
// double): the top vectors and singular values of a matrix with a decaying spectrum.
TEST(ClusterValues, IterativeSingularVectorsMatchTheExactSvd) {
  std::mt19937 rng(11);
  std::normal_distribution<float> normal(0.0f, 1.0f);
  const int n = 1500, dims = 400, rank = 12;
  Eigen::MatrixXf a(n, rank), b(rank, dims);
  for (int i = 0; i < n; ++i)
    for (int r = 0; r < rank; ++r) a(i, r) = normal(rng) * std::pow(0.5f, static_cast<float>(r));
  for (int r = 0; r < rank; ++r)
    for (int d = 0; d < dims; ++d) b(r, d) = normal(rng);
  Eigen::MatrixXf y = a * b;
  y.array() += 3.0f;  // same-signed, like ABRDFs: one dominant direction
  for (int i = 0; i < n; ++i)
    for (int d = 0; d < dims; ++d) y(i, d) += 0.01f * normal(rng);
  Eigen::MatrixXd yd = y.cast<double>();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(yd.transpose() * yd);
  Eigen::MatrixXd u;
  Eigen::VectorXd sigma;
  int iterations = 0;
  topLeftSingularVectors(y, 3, 1, u, sigma, &iterations);
  ASSERT_EQ(u.rows(), n);
  ASSERT_EQ(u.cols(), 3);
  EXPECT_LT(iterations, 200);
  for (int r = 0; r < 3; ++r) {
    const double exactSigma = std::sqrt(eig.eigenvalues()(dims - 1 - r));
    Eigen::VectorXd exact = yd * eig.eigenvectors().col(dims - 1 - r) / exactSigma;
    EXPECT_NEAR(sigma(r), exactSigma, 1e-5 * exactSigma) << "term " << r;
    EXPECT_GT(std::abs(exact.dot(u.col(r))), 1 - 1e-8) << "term " << r;
    EXPECT_NEAR(u.col(r).norm(), 1.0, 1e-6);
  }
  // Deterministic: the same seed gives the same bits.
  Eigen::MatrixXd u2;
  Eigen::VectorXd sigma2;
  topLeftSingularVectors(y, 3, 1, u2, sigma2);
  EXPECT_TRUE(u2 == u);
}

// A cluster above kExactSvdUpTo on both sides (1,152 texels, 3 x 361 values) takes the
// iterative way: its coefficients match the exact ones (the Gram matrix's eigenvectors), on any
// thread count.
TEST(ClusterValues, LargeClustersUseTheIterativeSvdAndMatchTheExactOne) {
  const int width = 36, height = 32, side = 19;
  std::vector<Direction> dirs;
  for (int i = 0; i < side; ++i) dirs.push_back({3.0 * i, 17.0 * i});
  BtfStack stack(dirs, dirs, width, height, SampleType::Half);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  std::vector<float> bright(width * height), tint(width * height);
  for (int t = 0; t < width * height; ++t) bright[t] = 0.5f + u01(rng), tint[t] = u01(rng);
  std::vector<float> rgb(width * height * 3);
  for (int image = 0; image < stack.numImages(); ++image) {
    const float lobe = 0.2f + 0.8f * u01(rng), second = u01(rng);
    for (int t = 0; t < width * height; ++t)
      for (int c = 0; c < 3; ++c)
        rgb[3 * t + c] = bright[t] * lobe * (1 + 0.1f * c) + 0.2f * tint[t] * second + 0.01f * u01(rng);
    stack.setImageLinear(image, rgb.data());
  }
  ASSERT_GT(std::min(width * height, 3 * stack.numImages()), kExactSvdUpTo);
  const std::vector<std::int32_t> ids(width * height, 0);
  const std::vector<std::uint8_t> use(stack.numImages(), 1);
  const float alpha = 2.0f;
  const int terms = 2;
  setThreadCount(1);
  const std::vector<float> one = texelCoefficients(stack, alpha, ids, 1, use, terms, false);
  setThreadCount(2);
  const std::vector<float> two = texelCoefficients(stack, alpha, ids, 1, use, terms, false);
  setThreadCount(0);
  EXPECT_EQ(one, two);
  const int n = width * height, dims = 3 * stack.numImages();
  Eigen::MatrixXd y(n, dims);
  for (int t = 0; t < n; ++t)
    for (int i = 0; i < stack.numImages(); ++i)
      for (int c = 0; c < 3; ++c) y(t, 3 * i + c) = stack.sample(i, t, c) / alpha;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(y * y.transpose());
  for (int r = 0; r < terms; ++r) {
    Eigen::VectorXd exact = eig.eigenvectors().col(n - 1 - r) * std::sqrt(static_cast<double>(n));
    if (exact.sum() < 0) exact = -exact;
    // (The first term's sign is fixed by a positive sum; a later term's sum can be near 0.)
    double worst[2] = {0, 0};
    for (int t = 0; t < n; ++t)
      for (int sign : {0, 1})
        worst[sign] = std::max(worst[sign], std::abs((sign ? -exact(t) : exact(t)) - one[static_cast<std::size_t>(t) * terms + r]));
    EXPECT_LT(r == 0 ? worst[0] : std::min(worst[0], worst[1]), 1e-4) << "term " << r;
  }
}

}  // namespace
}  // namespace nbtf
