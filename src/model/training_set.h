// What the optimizer sees, independent of torch: per-group targets, the image split and
// the per-step sample plan.
//
// A "group" is one encoder input (one latent): a cluster in the clustered mode, a texel in
// the per-texel mode. All texels of cluster c share one latent z_c, so
//   sum_{t in c} |f(z_c, l, v) - y_t|^2 = n_c |f(z_c, l, v) - ybar_c|^2 + sum_{t in c} |y_t - ybar_c|^2,
// i.e. training on the per-cluster mean targets ybar_c sampled in proportion to n_c
// optimizes exactly the per-texel loss, and its cost per epoch depends on k, not on the
// number of texels. The second term is a constant, kept per image for the exact RMSE.
#pragma once
#include <cstdint>
#include <vector>

#include "model/trainer.h"

namespace nbtf {

// SplitMix64: tiny, fast, and fully specified (unlike std:: distributions), so a seed
// gives the same samples on every platform. Streams are derived by hashing.
class SplitMix64 {
 public:
  explicit SplitMix64(std::uint64_t seed) : state_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (state_ += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  // Uniform integer in [0, n), n > 0 (Lemire's multiply-shift; bias < n / 2^64).
  std::uint64_t below(std::uint64_t n) {
    return static_cast<std::uint64_t>((static_cast<unsigned __int128>(next()) * n) >> 64);
  }
  static std::uint64_t mix(std::uint64_t a, std::uint64_t b) {
    SplitMix64 r(a ^ (b * 0xd1342543de82ef95ull + 0x2545f4914f6cdd1dull));
    r.next();
    return r.next();
  }

 private:
  std::uint64_t state_;
};

class TrainingSet {
 public:
  // Validates the inputs (throws nbtf::Error) and precomputes the cluster means in parallel.
  TrainingSet(const TrainInputs& inputs, double holdoutFraction, std::uint64_t seed, bool progress);

  bool perTexel() const { return perTexel_; }
  int groups() const { return groups_; }        // encoder inputs (rows of encoderInputs)
  int images() const { return images_; }        // N
  std::int64_t texels() const { return texels_; }  // M
  int groupSize(int g) const { return sizes_[g]; }
  const std::vector<int>& trainImages() const { return trainImages_; }
  const std::vector<int>& holdoutImages() const { return holdoutImages_; }
  bool isHoldout(int image) const { return holdout_[image] != 0; }
  // Sum over texels and channels of |y_t - ybar_c|^2 for one image (0 per texel).
  double withinSse(int image) const { return withinSse_.empty() ? 0.0 : withinSse_[image]; }
  // Stereographic (light x, y, view x, y) of every image: the decoder's direction input.
  const std::vector<float>& directions() const { return directions_; }

  // Mean target (linear / alpha) of group g for `count` images: out[3 * i + channel].
  void targets(int group, const int* images, int count, float* out) const;

  // Picks a group with probability n_g / M (uniform in the per-texel mode).
  int sampleGroup(SplitMix64& rng) const;

 private:
  void computeClusterMeans(const std::vector<std::int32_t>& ids, bool progress);

  const BtfStack* stack_;
  float alpha_;
  bool perTexel_;
  int groups_ = 0, images_ = 0;
  std::int64_t texels_ = 0;
  std::vector<int> sizes_;
  std::vector<std::int64_t> cumulative_;  // cumulative_[g] = sum of sizes before g, plus the total
  std::vector<int> trainImages_, holdoutImages_;
  std::vector<std::uint8_t> holdout_;
  std::vector<float> means_;      // groups x images x 3 (clustered only)
  std::vector<double> withinSse_; // images (clustered only)
  std::vector<float> directions_; // images x 4
};

// The samples of one optimizer step: `tiles` groups (drawn in proportion to their size),
// each with `imagesPerTile` distinct training images. A pure function of (seed, step), so a
// resumed run draws exactly what the uninterrupted one would have.
struct StepPlan {
  int tiles = 0, imagesPerTile = 0;
  std::vector<int> tileGroup;        // tiles
  std::vector<int> images;           // tiles x imagesPerTile
  std::vector<int> distinctGroups;   // groups to run the encoder on, each once
  std::vector<std::int64_t> tileSlot;  // tiles: index into distinctGroups
};

void planStep(const TrainingSet& set, std::uint64_t seed, std::int64_t step, int tiles, int imagesPerTile,
              StepPlan& plan);

}  // namespace nbtf
