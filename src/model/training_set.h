// What the optimizer sees, independent of torch: per-group targets, the image split and
// the per-step sample plan.
//
// A "group" is one encoder input (one latent): a cluster in the clustered mode, a texel in
// the per-texel mode. All texels of cluster c share one latent z_c, so
//   sum_{t in c} |f(z_c, l, v) - y_t|^2 = n_c |f(z_c, l, v) - ybar_c|^2 + sum_{t in c} |y_t - ybar_c|^2,
// i.e. training on the per-cluster mean targets ybar_c sampled in proportion to n_c
// optimizes exactly the per-texel loss, and its cost per epoch depends on k, not on the
// number of texels. The second term is a constant, kept per image for the exact RMSE.
// With per-texel modulation (coefficients e_t of R terms, orthonormal per cluster:
// sum_{t in c} e_tr e_tr' = n_c delta_rr') the same holds for the R RGB terms f_r the decoder
// outputs: the targets are T_r = sum_t e_tr y_t / n_c, the constant sum_t |y_t - sum_r e_tr
// T_r|^2 (cluster/cluster_values.h), and texel t's model value is sum_r e_tr f_r(z_c, l, v).
#pragma once
#include <cstdint>
#include <vector>

#include "model/trainer.h"

#include "util/direction_planes.h"
#include "util/random.h"

namespace nbtf {

// A step's rows read their images' values (directions, targets, plane taps) in random order:
// the loops over them request row r + kPrefetchRows's early, or they wait on cache misses
// most of their time.
constexpr int kPrefetchRows = 16;

// The hold-out split of `images` images: a deterministic random subset of round(fraction x
// images) (at least 1 when fraction > 0, at most images - 1); 1 = held out.
std::vector<std::uint8_t> holdoutImageMask(int images, double fraction, std::uint64_t seed);

class TrainingSet {
 public:
  // Validates the inputs (throws nbtf::Error) and precomputes the cluster means in parallel.
  TrainingSet(const TrainInputs& inputs, double holdoutFraction, std::uint64_t seed, bool progress,
              DirectionEncoding directionInputs = DirectionEncoding::Stereographic, int planeFeatures = 0,
              int planeResolution = 0, int clusterPlaneFeatures = 0, int clusterPlaneResolution = 0);

  bool perTexel() const { return perTexel_; }
  int groups() const { return groups_; }        // encoder inputs (rows of encoderInputs)
  int images() const { return images_; }        // N
  int outputs() const { return 3 * terms_; }    // targets per sample: RGB x modulation terms
  std::int64_t texels() const { return texels_; }  // M
  int groupSize(int g) const { return sizes_[g]; }
  const std::vector<int>& trainImages() const { return trainImages_; }
  const std::vector<int>& holdoutImages() const { return holdoutImages_; }
  bool isHoldout(int image) const { return holdout_[image] != 0; }
  // Sum over texels and channels of |y_t - ybar_c|^2 for one image (0 per texel).
  double withinSse(int image) const { return withinSse_.empty() ? 0.0 : withinSse_[image]; }
  // The same for the plain cluster means, when the model is modulated (else empty).
  const std::vector<double>& plainWithinSse() const { return plainWithinSse_; }
  // The decoder's direction input of every image (images x directionWidth(); util/directions.h):
  // the fixed encoding, then the direction planes' features (util/direction_planes.h) as the
  // last setPlaneFeatures gave them (zero before).
  const std::vector<float>& directions() const { return directions_; }
  int directionWidth() const { return directionWidth_; }
  int planeInputs() const { return planeInputs_; }
  // The per-cluster planes' inputs (the last 3 G columns; zero in directions()).
  int clusterPlaneInputs() const { return clusterPlaneInputs_; }
  std::size_t clusterPlaneValues() const { return clusterPlaneSize_; }  // per group
  // Writes group g's planes (`values`: clusterPlaneValues() floats) sampled at images[0..count)
  // into the last clusterPlaneInputs() columns of `rows` (directionWidth() floats each).
  void writeClusterPlaneFeatures(const float* values, const int* images, int count, float* rows) const;
  // Adds to `gradient` (one group's clusterPlaneValues() floats) the gradient from `count` rows
  // of dLoss/d(cluster plane features), `stride` floats apart.
  void addClusterPlaneGradient(const int* images, int count, const float* rowGradients, int stride,
                               float* gradient) const;
  // Samples `planes` (of the constructor's planeFeatures and planeResolution) at every
  // image's directions into the last planeInputs() columns. Parallel over images.
  void setPlaneFeatures(const DirectionPlanes& planes);
  // Adds to `gradient` (laid out as the planes' values) their gradient from rows of
  // dLoss/d(plane features): row r (planeInputs() floats) belongs to image images[r].
  // Rows are `stride` floats apart (planeInputs() when 0). Parallel over features, each
  // value's terms added in row order: the same bits on any number of threads.
  void addPlaneGradient(const int* images, const float* rowGradients, std::int64_t rows, float* gradient,
                        int stride = 0) const;
  // A hash of the per-texel coefficients (0 when there are none), for checkpoint fingerprints.
  std::uint64_t texelCoefficientHash() const { return coefficientHash_; }

  // Target (linear / alpha) of group g for `count` images: out[outputs() x i + 3 x term + channel].
  void targets(int group, const int* images, int count, float* out) const;

  // Picks a group with probability n_g / M (uniform in the per-texel mode).
  int sampleGroup(SplitMix64& rng) const;

 private:

  const BtfStack* stack_;
  float alpha_;
  bool perTexel_;
  int groups_ = 0, images_ = 0;
  std::int64_t texels_ = 0;
  std::vector<int> sizes_;
  std::vector<std::int64_t> cumulative_;  // cumulative_[g] = sum of sizes before g, plus the total
  std::vector<int> trainImages_, holdoutImages_;
  std::vector<std::uint8_t> holdout_;
  std::vector<float> means_;      // groups x images x outputs() (clustered only)
  std::vector<double> withinSse_; // images (clustered only)
  std::vector<double> plainWithinSse_;  // images (modulated only)
  std::vector<float> directions_; // images x directionWidth_
  int directionWidth_ = 4;
  int planeInputs_ = 0;
  int clusterPlaneInputs_ = 0, clusterPlaneResolution_ = 0;
  std::size_t clusterPlaneSize_ = 0;
  int planeFeatures_ = 0, planeResolution_ = 0;
  // Per image, where its (light, view) pair falls on the shared and on the cluster planes'
  // grids (util/direction_planes.h); empty without such planes.
  std::vector<PlaneTaps> planeTaps_, clusterPlaneTaps_;
  std::uint64_t coefficientHash_ = 0;
  int terms_ = 1;
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
