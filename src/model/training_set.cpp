#include "model/training_set.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <utility>

#include <ATen/Parallel.h>

#include "cluster/cluster_values.h"
#include "util/error.h"
#include "util/parallel.h"
#include "util/progress.h"

namespace nbtf {
namespace {
// Independent random streams derived from the one seed.
constexpr std::uint64_t kHoldoutStream = 0x686f6c646f7574ull;  // "holdout"
constexpr std::uint64_t kStepStream = 0x73746570ull;           // "step"

// Throws unless the encoder inputs and alpha fit the stack.
void checkEncoderInputs(const TrainInputs& in, int images, std::int64_t texels, int groups) {
  const MatrixXfCol& x = *in.encoderInputs;
  if (images < 1 || texels < 1) throw Error("training: the BTF stack is empty");
  if (x.cols() != 3 * static_cast<Eigen::Index>(images))
    throw Error("training: encoder inputs have " + std::to_string(x.cols()) + " columns, expected 3 x " +
                std::to_string(images) + " images");
  if (groups < 1) throw Error("training: no encoder inputs (0 rows)");
  if (!(in.alpha > 0) || !std::isfinite(in.alpha))
    throw Error("training: alpha must be a positive finite number, got " + std::to_string(in.alpha));
  if (!x.allFinite()) throw Error("training: encoder inputs contain NaN or infinity");
}

// The texels of each encoder input: 1 per-texel, else the ids' counts.
std::vector<int> groupSizes(const TrainInputs& in, bool perTexel, int groups, std::int64_t texels) {
  std::vector<int> sizes;
  if (perTexel) {
    if (groups != texels)
      throw Error("training: per-texel mode needs one encoder input per texel (" + std::to_string(texels) +
                  "), got " + std::to_string(groups));
    sizes.assign(groups, 1);
    return sizes;
  }
  if (static_cast<std::int64_t>(in.ids.size()) != texels)
    throw Error("training: id list has " + std::to_string(in.ids.size()) + " entries for " +
                std::to_string(texels) + " texels");
  sizes.assign(groups, 0);
  for (std::size_t t = 0; t < in.ids.size(); ++t) {
    std::int32_t id = in.ids[t];
    if (id < 0 || id >= groups)
      throw Error("training: texel " + std::to_string(t) + " has cluster id " + std::to_string(id) +
                  ", outside 0.." + std::to_string(groups - 1));
    ++sizes[id];
  }
  return sizes;
}

// Checks the per-texel coefficients' count and values; returns their FNV-1a hash over the bits.
std::uint64_t checkedCoefficientHash(const TrainInputs& in, std::int64_t texels) {
  const int terms = in.coefficientTerms, channels = in.coefficientChannels;
  if (terms < 1 || (channels != 1 && channels != 3) ||
      static_cast<std::int64_t>(in.texelCoefficients.size()) != texels * terms * channels)
    throw Error("training: " + std::to_string(in.texelCoefficients.size()) + " per-texel coefficients for " +
                std::to_string(texels) + " texels x " + std::to_string(in.coefficientTerms) + " terms x " +
                std::to_string(channels) + " channels");
  for (float f : in.texelCoefficients)
    if (!std::isfinite(f)) throw Error("training: per-texel coefficients must be finite");
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (float f : in.texelCoefficients) {
    std::uint32_t bits;
    std::memcpy(&bits, &f, 4);
    h = (h ^ bits) * 0x100000001b3ull;
  }
  return h;
}
}  // namespace

TrainingSet::TrainingSet(const TrainInputs& in, double holdoutFraction, std::uint64_t seed, bool progress,
                         DirectionEncoding directionInputs, int planeFeatures, int planeResolution,
                         int clusterPlaneFeatures, int clusterPlaneResolution)
    : stack_(in.stack), alpha_(in.alpha), perTexel_(in.ids.empty()) {
  // ---- Validate: every mismatch here would otherwise be a wrong answer, not a crash.
  if (!in.stack) throw Error("training: no BTF stack given");
  if (!in.encoderInputs) throw Error("training: no encoder inputs given");
  const BtfStack& stack = *in.stack;
  images_ = stack.numImages();
  texels_ = stack.numTexels();
  groups_ = static_cast<int>(in.encoderInputs->rows());
  checkEncoderInputs(in, images_, texels_, groups_);
  sizes_ = groupSizes(in, perTexel_, groups_, texels_);
  cumulative_.resize(groups_ + 1);
  cumulative_[0] = 0;
  for (int g = 0; g < groups_; ++g) cumulative_[g + 1] = cumulative_[g] + sizes_[g];

  // ---- Hold-out images: a deterministic random subset, at least one image stays for training.
  holdout_ = holdoutImageMask(images_, holdoutFraction, seed);
  for (int i = 0; i < images_; ++i) (holdout_[i] ? holdoutImages_ : trainImages_).push_back(i);

  // ---- Decoder direction inputs (eq. 7-9).
  planeInputs_ = DirectionPlanes::kPlanes * planeFeatures;
  planeFeatures_ = planeFeatures;
  planeResolution_ = planeResolution;
  for (auto [features, resolution] : {std::pair{planeFeatures, planeResolution},
                                      std::pair{clusterPlaneFeatures, clusterPlaneResolution}})
    if (features > 0 && resolution < 2)
      throw Error("training: planes of " + std::to_string(resolution) + " grid points per side (at least 2)");
  clusterPlaneInputs_ = DirectionPlanes::kPlanes * clusterPlaneFeatures;
  clusterPlaneResolution_ = clusterPlaneResolution;
  clusterPlaneSize_ = static_cast<std::size_t>(clusterPlaneInputs_) * clusterPlaneResolution * clusterPlaneResolution;
  directionWidth_ = directionInputCount(directionInputs) + planeInputs_ + clusterPlaneInputs_;
  directions_.assign(static_cast<std::size_t>(images_) * directionWidth_, 0.0f);
  for (int i = 0; i < images_; ++i) {
    const Direction& light = stack.lights()[i / stack.numViews()];
    const Direction& view = stack.views()[i % stack.numViews()];
    encodeDirections(directionInputs, light, view, &directions_[static_cast<std::size_t>(i) * directionWidth_]);
    // Where the pair falls on each kind of planes' grid, found once: every step samples and
    // scatters the same pairs.
    if (planeInputs_ + clusterPlaneInputs_ > 0) {
      float points[6];
      directionPlanePoints(light.unitVector(), view.unitVector(), points);
      if (planeInputs_ > 0) planeTaps_.push_back(planeTaps(planeResolution_, points));
      if (clusterPlaneInputs_ > 0) clusterPlaneTaps_.push_back(planeTaps(clusterPlaneResolution_, points));
    }
  }

  if (!perTexel_) {
    const float* coefficients = nullptr;
    int channels = 1;
    if (!in.texelCoefficients.empty()) {
      terms_ = in.coefficientTerms;
      channels = in.coefficientChannels;
      coefficientHash_ = checkedCoefficientHash(in, texels_);
      coefficients = in.texelCoefficients.data();
    }
    // With coefficients, the plain cluster means' leftover too: the floor the summary reports
    // beside the modulated one, from the same pass over the stack.
    ClusterValues values =
        clusterValues(stack, alpha_, in.ids, groups_, coefficients, terms_, true, progress, channels, coefficients);
    means_ = std::move(values.means);
    withinSse_ = std::move(values.withinSse);
    plainWithinSse_ = std::move(values.plainWithinSse);
  } else if (!in.texelCoefficients.empty()) {
    throw Error("training: per-texel modulation needs the clustered mode");
  }
}

std::vector<std::uint8_t> holdoutImageMask(int images, double fraction, std::uint64_t seed) {
  std::vector<std::uint8_t> mask(images, 0);
  int held = fraction > 0 ? static_cast<int>(std::lround(fraction * images)) : 0;
  if (fraction > 0) held = std::max(held, 1);
  held = std::min(held, images - 1);
  std::vector<int> order(images);
  for (int i = 0; i < images; ++i) order[i] = i;
  SplitMix64 rng(SplitMix64::mix(seed, kHoldoutStream));
  for (int i = 0; i < held; ++i) std::swap(order[i], order[i + rng.below(images - i)]);
  for (int i = 0; i < held; ++i) mask[order[i]] = 1;
  return mask;
}

void TrainingSet::targets(int group, const int* images, int count, float* out) const {
  if (!perTexel_) {
    const std::size_t o = static_cast<std::size_t>(outputs());
    const float* m = &means_[static_cast<std::size_t>(group) * images_ * o];
    for (int s = 0; s < count; ++s) {
      if (s + kPrefetchRows < count) __builtin_prefetch(m + o * images[s + kPrefetchRows]);  // random images
      std::memcpy(out + o * s, m + o * images[s], o * sizeof(float));
    }
    return;
  }
  const float invAlpha = 1.0f / alpha_;
  for (int s = 0; s < count; ++s)
    for (int c = 0; c < 3; ++c) out[3 * s + c] = stack_->sample(images[s], group, c) * invAlpha;
}

int TrainingSet::sampleGroup(SplitMix64& rng) const {
  if (perTexel_) return static_cast<int>(rng.below(groups_));
  std::int64_t u = static_cast<std::int64_t>(rng.below(static_cast<std::uint64_t>(texels_)));
  // The group whose [cumulative_[g], cumulative_[g + 1]) holds u; empty clusters are never hit.
  auto it = std::upper_bound(cumulative_.begin(), cumulative_.end(), u);
  return static_cast<int>(it - cumulative_.begin()) - 1;
}

void planStep(const TrainingSet& set, std::uint64_t seed, std::int64_t step, int tiles, int imagesPerTile,
              StepPlan& plan) {
  const std::vector<int>& train = set.trainImages();
  const int n = static_cast<int>(train.size());
  imagesPerTile = std::min(imagesPerTile, n);
  plan.tiles = tiles;
  plan.imagesPerTile = imagesPerTile;
  plan.tileGroup.resize(tiles);
  plan.images.resize(static_cast<std::size_t>(tiles) * imagesPerTile);
  SplitMix64 rng(SplitMix64::mix(SplitMix64::mix(seed, kStepStream), static_cast<std::uint64_t>(step)));
  // Distinct images per tile: a partial Fisher-Yates shuffle on a scratch copy, undone after.
  std::vector<int> scratch(train);
  std::vector<int> swaps(imagesPerTile);
  for (int t = 0; t < tiles; ++t) {
    plan.tileGroup[t] = set.sampleGroup(rng);
    int* out = &plan.images[static_cast<std::size_t>(t) * imagesPerTile];
    if (imagesPerTile == n) {
      std::copy(train.begin(), train.end(), out);
      continue;
    }
    for (int s = 0; s < imagesPerTile; ++s) {
      int j = s + static_cast<int>(rng.below(n - s));
      swaps[s] = j;
      std::swap(scratch[s], scratch[j]);
      out[s] = scratch[s];
    }
    for (int s = imagesPerTile - 1; s >= 0; --s) std::swap(scratch[s], scratch[swaps[s]]);
  }
  plan.distinctGroups = plan.tileGroup;
  std::sort(plan.distinctGroups.begin(), plan.distinctGroups.end());
  plan.distinctGroups.erase(std::unique(plan.distinctGroups.begin(), plan.distinctGroups.end()),
                            plan.distinctGroups.end());
  plan.tileSlot.resize(tiles);
  for (int t = 0; t < tiles; ++t)
    plan.tileSlot[t] = std::lower_bound(plan.distinctGroups.begin(), plan.distinctGroups.end(), plan.tileGroup[t]) -
                       plan.distinctGroups.begin();
}

void TrainingSet::setPlaneFeatures(const DirectionPlanes& planes) {
  if (planeInputs_ == 0) return;
  if (planes.resolution != planeResolution_ || planes.features != planeFeatures_)
    throw Error("training: direction planes of " + std::to_string(planes.resolution) + " x " +
                std::to_string(planes.features) + " given to a set built for " + std::to_string(planeResolution_) +
                " x " + std::to_string(planeFeatures_));
  const int first = directionWidth_ - clusterPlaneInputs_ - planeInputs_;
  at::parallel_for(0, images_, 256, [&](std::int64_t begin, std::int64_t end) {
    for (std::int64_t i = begin; i < end; ++i)
      sampleDirectionPlanes(planeTaps_[i], planeResolution_, planeFeatures_, planes.values.data(),
                            &directions_[static_cast<std::size_t>(i) * directionWidth_ + first]);
  });
}

void TrainingSet::addPlaneGradient(const int* images, const float* rowGradients, std::int64_t rows, float* gradient,
                                   int stride) const {
  if (stride == 0) stride = planeInputs_;
  const std::size_t values = static_cast<std::size_t>(planeInputs_) * planeResolution_ * planeResolution_;
  at::parallel_for(0, planeFeatures_, 1, [&](std::int64_t firstFeature, std::int64_t endFeature) {
    // A copy of its own, so that threads do not write to one another's cache lines.
    std::vector<float> own(gradient, gradient + values);
    for (std::int64_t r = 0; r < rows; ++r) {
      if (r + kPrefetchRows < rows) {
        const char* ahead = reinterpret_cast<const char*>(&planeTaps_[images[r + kPrefetchRows]]);
        __builtin_prefetch(ahead);
        __builtin_prefetch(ahead + sizeof(PlaneTaps) - 1);
      }
      scatterDirectionPlanesGradient(planeTaps_[images[r]], planeResolution_, planeFeatures_, rowGradients + r * stride,
                                     own.data(), static_cast<int>(firstFeature), static_cast<int>(endFeature));
    }
    for (std::size_t v = 0; v < values; v += planeFeatures_)
      std::copy(&own[v + firstFeature], &own[v + endFeature], gradient + v + firstFeature);
  });
}

void TrainingSet::writeClusterPlaneFeatures(const float* values, const int* images, int count, float* rows) const {
  const int first = directionWidth_ - clusterPlaneInputs_, G = clusterPlaneInputs_ / DirectionPlanes::kPlanes;
  for (int r = 0; r < count; ++r)
    sampleDirectionPlanes(clusterPlaneTaps_[images[r]], clusterPlaneResolution_, G, values,
                          rows + static_cast<std::size_t>(r) * directionWidth_ + first);
}

void TrainingSet::addClusterPlaneGradient(const int* images, int count, const float* rowGradients, int stride,
                                          float* gradient) const {
  const int G = clusterPlaneInputs_ / DirectionPlanes::kPlanes;
  for (int r = 0; r < count; ++r)
    scatterDirectionPlanesGradient(clusterPlaneTaps_[images[r]], clusterPlaneResolution_, G,
                                   rowGradients + static_cast<std::size_t>(r) * stride, gradient, 0, G);
}

}  // namespace nbtf
