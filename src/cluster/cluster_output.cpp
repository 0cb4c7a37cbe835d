#include "cluster/cluster_output.h"

#include <algorithm>
#include <cstdio>
#include <numeric>
#include <sstream>

#include "io/color.h"
#include "util/error.h"
#include "util/parallel.h"

namespace nbtf {

// ---- Label colours
//
// x -> odd multiply, xor-shift, odd multiply, xor-shift, all modulo 2^24: each step is a
// bijection on 24 bits, so is the whole.

namespace {
constexpr std::uint32_t kMask = 0xFFFFFF;
constexpr std::uint32_t kMul1 = 0x9E3779, kMul2 = 0xC2B2AF, kAdd = 0x7F4A7C;

// Inverse of x * a (mod 2^24) for odd a, by Newton's iteration on the 2-adic inverse.
std::uint32_t inverseMod24(std::uint32_t a) {
  std::uint32_t inv = a;  // correct to 3 bits for odd a
  for (int i = 0; i < 5; ++i) inv = (inv * (2 - a * inv)) & kMask;
  return inv;
}
std::uint32_t unxorshift12(std::uint32_t y) { return y ^ (y >> 12); }  // x ^ (x >> 12) is its own inverse on 24 bits
}  // namespace

std::array<std::uint8_t, 3> labelColour(int id) {
  std::uint32_t x = static_cast<std::uint32_t>(id) & kMask;
  x = (x * kMul1 + kAdd) & kMask;
  x ^= x >> 12;
  x = (x * kMul2) & kMask;
  x ^= x >> 12;
  return {static_cast<std::uint8_t>(x >> 16), static_cast<std::uint8_t>(x >> 8), static_cast<std::uint8_t>(x)};
}

int labelFromColour(const std::uint8_t* rgb) {
  std::uint32_t x = (std::uint32_t(rgb[0]) << 16) | (std::uint32_t(rgb[1]) << 8) | rgb[2];
  x = unxorshift12(x);
  x = (x * inverseMod24(kMul2)) & kMask;
  x = unxorshift12(x);
  x = ((x - kAdd) * inverseMod24(kMul1)) & kMask;
  return static_cast<int>(x);
}

Image8 labelImage(const std::vector<std::int32_t>& ids, int width, int height) {
  if (static_cast<std::size_t>(width) * height != ids.size()) {
    std::ostringstream s;
    s << "label image: " << ids.size() << " ids do not fill " << width << " x " << height << " texels";
    throw Error(s.str());
  }
  Image8 image;
  image.width = width, image.height = height;
  image.rgb.resize(ids.size() * 3);
  for (std::size_t t = 0; t < ids.size(); ++t) {
    auto c = labelColour(ids[t]);
    std::copy(c.begin(), c.end(), image.rgb.begin() + 3 * t);
  }
  return image;
}

// ---- Appearance

Eigen::MatrixXf texelMeanColour(const MatrixXfCol& linearAbrdfs) {
  const Eigen::Index m = linearAbrdfs.rows(), images = linearAbrdfs.cols() / 3;
  if (images == 0 || linearAbrdfs.cols() % 3 != 0) throw Error("texel colours: expected 3 columns per image");
  Eigen::MatrixXf out(m, 3);
  // Texel ranges in parallel; within a range, columns in order (contiguous reads).
  parallelFor(m, [&](std::size_t begin, std::size_t end) {
    Eigen::ArrayXXd sum = Eigen::ArrayXXd::Zero(end - begin, 3);
    for (Eigen::Index d = 0; d < linearAbrdfs.cols(); ++d)
      sum.col(d % 3) += linearAbrdfs.col(d).segment(begin, end - begin).cast<double>().array();
    out.middleRows(begin, end - begin) = (sum / static_cast<double>(images)).cast<float>().matrix();
  }, 256);
  return out;
}

Eigen::MatrixXf texelMeanColour(const BtfStack& stack) {
  const Eigen::Index m = stack.numTexels();
  const int images = stack.numImages();
  if (images == 0) throw Error("texel colours: the stack has no images");
  Eigen::MatrixXf out(m, 3);
  // Texel ranges in parallel; within a range, images in order: the sums of the matrix version.
  // A range is read image by image as one span (copied out of a stack in a scratch file), not
  // texel by texel across all images, which would map every page of such a file at once.
  constexpr std::size_t kSpan = 2048;
  parallelFor(m, [&](std::size_t begin, std::size_t end) {
    std::vector<int> texels;
    std::vector<float> values;
    for (std::size_t first = begin; first < end; first += kSpan) {
      const int n = static_cast<int>(std::min(kSpan, end - first));
      texels.resize(n);
      std::iota(texels.begin(), texels.end(), static_cast<int>(first));
      values.resize(3 * static_cast<std::size_t>(n));
      Eigen::ArrayXXd sum = Eigen::ArrayXXd::Zero(n, 3);
      for (int image = 0; image < images; ++image) {
        stack.gatherLinear(&image, 1, texels.data(), n, values.data());  // values[c * n + i]
        for (int c = 0; c < 3; ++c)
          for (int i = 0; i < n; ++i) sum(i, c) += static_cast<double>(values[static_cast<std::size_t>(c) * n + i]);
      }
      out.middleRows(static_cast<Eigen::Index>(first), n) = (sum / static_cast<double>(images)).cast<float>().matrix();
    }
  }, 256);
  return out;
}

Eigen::MatrixXf clusterMeanColour(const Eigen::MatrixXf& texelColour, const std::vector<std::int32_t>& ids, int k) {
  if (static_cast<Eigen::Index>(ids.size()) != texelColour.rows()) throw Error("cluster colours: one id per texel expected");
  Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(k, 3);
  std::vector<int> count(k, 0);
  for (std::size_t t = 0; t < ids.size(); ++t) {
    if (ids[t] < 0 || ids[t] >= k) throw Error("cluster colours: id " + std::to_string(ids[t]) + " out of range");
    sum.row(ids[t]) += texelColour.row(t).cast<double>();
    ++count[ids[t]];
  }
  Eigen::MatrixXf out(ids.size(), 3);
  for (std::size_t t = 0; t < ids.size(); ++t) out.row(t) = (sum.row(ids[t]) / count[ids[t]]).cast<float>();
  return out;
}

Image8 colourImage(const Eigen::MatrixXf& rgb, int width, int height, float scale) {
  if (rgb.rows() != static_cast<Eigen::Index>(width) * height || rgb.cols() != 3)
    throw Error("colour image: " + std::to_string(rgb.rows()) + " colours do not fill " + std::to_string(width) + " x " +
                std::to_string(height) + " texels");
  Image8 image;
  image.width = width, image.height = height;
  image.rgb.resize(static_cast<std::size_t>(width) * height * 3);
  const float inverse = scale > 0 ? 1.0f / scale : 1.0f;
  for (Eigen::Index t = 0; t < rgb.rows(); ++t)
    for (int c = 0; c < 3; ++c) image.rgb[3 * t + c] = linearToSrgb8(rgb(t, c) * inverse);
  return image;
}

// ---- Sizes

std::vector<SizeBin> sizeHistogram(const std::vector<int>& sizes) {
  std::vector<SizeBin> bins;
  int largest = sizes.empty() ? 0 : *std::max_element(sizes.begin(), sizes.end());
  if (std::count(sizes.begin(), sizes.end(), 0) > 0)
    bins.push_back({0, 0, static_cast<int>(std::count(sizes.begin(), sizes.end(), 0))});
  for (long lo = 1; lo <= largest; lo *= 2) {
    long hi = 2 * lo - 1;
    int n = static_cast<int>(std::count_if(sizes.begin(), sizes.end(), [&](int s) { return s >= lo && s <= hi; }));
    bins.push_back({static_cast<int>(lo), static_cast<int>(std::min<long>(hi, largest)), n});
  }
  return bins;
}

// ---- Summary

nlohmann::json clusteringSummary(const ClusteringResult& result, const ClusteringOptions& options,
                                 const ClusterRunInfo& info) {
  using nlohmann::json;
  const int k = static_cast<int>(result.sizes.size());
  std::vector<int> sorted = result.sizes;
  std::sort(sorted.begin(), sorted.end());
  const double texels = static_cast<double>(result.ids.size());

  json j;
  j["input"] = info.input;
  j["texels"] = result.ids.size();
  j["width"] = info.width;
  j["height"] = info.height;
  j["images"] = info.images;
  j["dimensions"] = result.representatives.cols();
  if (!info.crop.empty()) j["crop"] = {info.crop.x, info.crop.y, info.crop.width, info.crop.height};
  j["seed"] = options.seed;
  j["threads"] = info.threads;
  j["target_alpha_linear"] = info.alpha;
  j["pca"] = {{"components", result.explainedVariance.size()},
              {"power_iterations", options.pca.powerIterations},
              {"oversampling", options.pca.oversampling},
              {"sample_mib", options.pca.sampleBytes >> 20},
              {"sampled_texels", result.pcaSampledTexels},
              {"space", info.space == ClusteringSpace::Linear ? "linear ABRDFs / alpha" : "standardized log(x + 1) ABRDFs"},
              {"explained_variance_ratio", result.explainedVarianceRatio},
              {"explained_variance", std::vector<float>(result.explainedVariance.data(),
                                                        result.explainedVariance.data() +
                                                            result.explainedVariance.size())}};
  j["kmeans"] = {{"k", k},
                 {"seeding", "k-means++ (D(x)^2 sampling), " +
                                 std::to_string(seedingTrialsFor(k, options.kmeans.seedingTrials)) +
                                 " candidates per step"},
                 {"inertia", result.inertia},
                 {"inertia_per_texel", texels > 0 ? result.inertia / texels : 0.0},
                 {"inertia_space", "sum of squared distances to the cluster centre in PCA space"},
                 {"iterations", result.iterations},
                 {"converged", result.converged},
                 {"last_moved_texels", result.lastMoved},
                 {"reseeded_clusters", result.reseeded},
                 {"empty_clusters", result.emptyClusters}};
  j["representative"] = options.representative == Representative::Median ? "per-dimension median" : "mean";
  j["cluster_sizes"] = {{"min", sorted.empty() ? 0 : sorted.front()},
                        {"median", sorted.empty() ? 0 : sorted[sorted.size() / 2]},
                        {"max", sorted.empty() ? 0 : sorted.back()},
                        {"mean", k > 0 ? texels / k : 0.0}};
  json histogram = json::array();
  for (const SizeBin& b : sizeHistogram(result.sizes))
    histogram.push_back({{"sizes", {b.smallest, b.largest}}, {"clusters", b.clusters}});
  j["size_histogram"] = histogram;
  json clusters = json::array();
  for (int c = 0; c < k; ++c) {
    auto rgb = labelColour(c);
    char hex[8];
    std::snprintf(hex, sizeof hex, "#%02x%02x%02x", rgb[0], rgb[1], rgb[2]);
    clusters.push_back({{"id", c}, {"size", result.sizes[c]}, {"colour", hex}});
  }
  j["clusters"] = clusters;
  if (info.peakMemoryBytes > 0) j["peak_memory_bytes"] = info.peakMemoryBytes;
  j["seconds"] = {{"load", info.loadSeconds},
                  {"texel_colours", info.matrixSeconds},
                  {"standardize", info.standardizeSeconds},
                  {"pca", result.pcaSeconds},
                  {"kmeans", result.kmeansSeconds},
                  {"representatives", result.representativeSeconds},
                  {"total", info.totalSeconds}};
  return j;
}

}  // namespace nbtf
