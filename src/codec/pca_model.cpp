#include "codec/pca_model.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "util/error.h"

namespace nbtf {
namespace {

// Great-circle angle between unit vectors, in radians (atan2 form: accurate near 0 and pi,
// where acos of a rounded dot product is not).
double angleBetween(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  double cx = a[1] * b[2] - a[2] * b[1], cy = a[2] * b[0] - a[0] * b[2], cz = a[0] * b[1] - a[1] * b[0];
  double dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  return std::atan2(std::sqrt(cx * cx + cy * cy + cz * cz), dot);
}

std::vector<std::array<double, 3>> unitVectors(const std::vector<Direction>& set) {
  std::vector<std::array<double, 3>> v;
  v.reserve(set.size());
  for (const Direction& d : set) v.push_back(d.unitVector());
  return v;
}

struct Candidate {
  double distance;
  int image;
  bool operator<(const Candidate& o) const { return distance != o.distance ? distance < o.distance : image < o.image; }
};

// Indices of the `count` smallest angles (ties by index), ascending.
std::vector<int> nearestIndices(const std::vector<double>& angles, int count) {
  std::vector<int> order(angles.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  count = std::min<int>(count, static_cast<int>(order.size()));
  std::partial_sort(order.begin(), order.begin() + count, order.end(), [&](int a, int b) {
    return angles[a] != angles[b] ? angles[a] < angles[b] : a < b;
  });
  order.resize(count);
  return order;
}

// Below this pair distance (radians, about 6e-8 degrees) a query is the measured pair.
constexpr double kSamePair = 1e-9;

}  // namespace

DirectionInterpolator::DirectionInterpolator(const std::vector<Direction>& lights, const std::vector<Direction>& views,
                                             std::vector<std::uint8_t> usable)
    : lights_(unitVectors(lights)), views_(unitVectors(views)), usable_(std::move(usable)) {
  const std::size_t images = lights_.size() * views_.size();
  if (images == 0) throw Error("PCA interpolation: no measured directions");
  if (!usable_.empty()) {
    if (usable_.size() != images)
      throw Error("PCA interpolation: usable-image mask has " + std::to_string(usable_.size()) + " entries for " +
                  std::to_string(images) + " images");
    if (std::none_of(usable_.begin(), usable_.end(), [](std::uint8_t u) { return u != 0; }))
      throw Error("PCA interpolation: no usable image");
    if (std::all_of(usable_.begin(), usable_.end(), [](std::uint8_t u) { return u != 0; })) usable_.clear();
  }
}

std::vector<ImageWeight> DirectionInterpolator::weights(const Direction& light, const Direction& view) const {
  return weights(light.unitVector(), view.unitVector());
}

std::vector<ImageWeight> DirectionInterpolator::weights(const std::array<double, 3>& l,
                                                        const std::array<double, 3>& v) const {
  const int nv = static_cast<int>(views_.size());
  std::vector<double> la(lights_.size()), va(views_.size());
  for (std::size_t i = 0; i < lights_.size(); ++i) la[i] = angleBetween(l, lights_[i]);
  for (std::size_t j = 0; j < views_.size(); ++j) va[j] = angleBetween(v, views_[j]);

  // ---- The K + 1 nearest usable pairs. With every pair usable they lie among the K + 1
  // nearest lights x the K + 1 nearest views (a pair with a farther light is beaten by K + 1
  // pairs of nearer lights with the same view); with a mask, search all pairs.
  const int want = kPcaNeighbours + 1;
  std::vector<Candidate> candidates;
  if (usable_.empty()) {
    std::vector<int> nl = nearestIndices(la, want), nvs = nearestIndices(va, want);
    for (int i : nl)
      for (int j : nvs) candidates.push_back({std::hypot(la[i], va[j]), i * nv + j});
  } else {
    for (std::size_t i = 0; i < la.size(); ++i)
      for (int j = 0; j < nv; ++j) {
        int image = static_cast<int>(i) * nv + j;
        if (usable_[image]) candidates.push_back({std::hypot(la[i], va[j]), image});
      }
  }
  const int keep = std::min<int>(want, static_cast<int>(candidates.size()));
  std::partial_sort(candidates.begin(), candidates.begin() + keep, candidates.end());
  candidates.resize(keep);

  // ---- Modified Shepard weights.
  std::vector<ImageWeight> out;
  if (candidates.front().distance < kSamePair) {
    out.push_back({candidates.front().image, 1.0});
    return out;
  }
  const int used = std::min(kPcaNeighbours, keep);
  // Fewer than K + 1 usable pairs: no outer radius, plain inverse-distance-squared weights.
  const double radius = keep > kPcaNeighbours ? candidates[kPcaNeighbours].distance
                                              : std::numeric_limits<double>::infinity();
  double sum = 0;
  for (int k = 0; k < used; ++k) {
    const double d = candidates[k].distance;
    const double w = std::isinf(radius) ? 1.0 / (d * d) : std::pow(std::max(0.0, radius - d) / (radius * d), 2);
    if (w > 0) {
      out.push_back({candidates[k].image, w});
      sum += w;
    }
  }
  if (!(sum > 0)) {
    // Every one of the K nearest is as far as the (K + 1)-th (a tie on a symmetric grid):
    // equal weights over the nearest ones.
    out.clear();
    for (int k = 0; k < used && candidates[k].distance == candidates[0].distance; ++k)
      out.push_back({candidates[k].image, 1.0});
    sum = static_cast<double>(out.size());
  }
  for (ImageWeight& w : out) w.weight /= sum;
  std::stable_sort(out.begin(), out.end(), [](const ImageWeight& a, const ImageWeight& b) { return a.weight > b.weight; });
  return out;
}

void combinePcaRows(const float* mean, const float* basis, int components, const std::vector<ImageWeight>& weights,
                    float* meanOut, float* basisOut) {
  const std::size_t c = static_cast<std::size_t>(components);
  if (weights.size() == 1 && weights[0].weight == 1.0) {
    const std::size_t row = 3 * static_cast<std::size_t>(weights[0].image);
    std::copy(mean + row, mean + row + 3, meanOut);
    std::copy(basis + row * c, basis + (row + 3) * c, basisOut);
    return;
  }
  std::vector<double> acc(3 * c + 3, 0.0);
  for (const ImageWeight& w : weights) {
    const std::size_t row = 3 * static_cast<std::size_t>(w.image);
    for (int ch = 0; ch < 3; ++ch) acc[3 * c + ch] += w.weight * mean[row + ch];
    const float* b = basis + row * c;
    for (std::size_t k = 0; k < 3 * c; ++k) acc[k] += w.weight * b[k];
  }
  for (int ch = 0; ch < 3; ++ch) meanOut[ch] = static_cast<float>(acc[3 * c + ch]);
  for (std::size_t k = 0; k < 3 * c; ++k) basisOut[k] = static_cast<float>(acc[k]);
}

void pcaTexelValue(const float* coefficients, const float* mean3, const float* basis3, int components, float* rgb) {
  // Eight partial sums: the compiler vectorizes them, and the order is fixed, so every
  // path (single query, batch, whole image) gives the same bits.
  for (int ch = 0; ch < 3; ++ch) {
    const float* b = basis3 + static_cast<std::size_t>(ch) * components;
    float s[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    int k = 0;
    for (; k + 8 <= components; k += 8)
      for (int j = 0; j < 8; ++j) s[j] += coefficients[k + j] * b[k + j];
    for (int j = 0; k < components; ++k, ++j) s[j] += coefficients[k] * b[k];
    rgb[ch] = mean3[ch] + (((s[0] + s[1]) + (s[2] + s[3])) + ((s[4] + s[5]) + (s[6] + s[7])));
  }
}

}  // namespace nbtf
