// The PCA baseline's representation, shared by its compressor and the decoder:
//
//   value(texel t, image i, channel c) = mean[3 i + c] + coefficients(t) . basis(3 i + c)
//
// in linear RGB / alpha, with C components: mean (3N floats), basis (3N rows of C floats,
// one row per image channel), coefficients (one row of C floats per texel).
//
// PCA only knows the measured (light, view) images. Any other pair is answered by
// interpolating the mean and the basis rows over neighbouring measured pairs (then one dot
// product per texel and channel, as at a measured pair). The rule (docs/file_format.md,
// "PCA baseline"): the distance between pairs is
//   d = sqrt(angle(light, light_i)^2 + angle(view, view_i)^2)   (great-circle angles),
// the K = 8 nearest measured pairs are weighted by modified Shepard weights
//   w_i = ((R - d_i) / (R d_i))^2,  R = d of the 9th nearest,
// normalized to sum 1. A measured pair (d = 0) gets weight 1 alone, so measured images are
// reproduced exactly; weights are >= 0 (values lie between the neighbours'); and a pair
// entering or leaving the K nearest does so with weight 0, so the interpolation is
// continuous in the directions (plain K-nearest inverse-distance weighting jumps there).
// Hold-out images are filled at compression time by the same rule over the fitted images.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include "util/directions.h"

namespace nbtf {

// Neighbours the interpolation blends (the weights also look at one more, for R).
constexpr int kPcaNeighbours = 8;

struct ImageWeight {
  int image = 0;      // light * views + view
  double weight = 0;  // > 0; the weights of one query sum to 1
};

// Interpolation weights over the measured (light, view) pairs.
class DirectionInterpolator {
 public:
  // `usable`: per image, nonzero if it may be used (empty = every image). At least one
  // image must be usable.
  DirectionInterpolator(const std::vector<Direction>& lights, const std::vector<Direction>& views,
                        std::vector<std::uint8_t> usable = {});

  // At most kPcaNeighbours weights, largest first (ties by image index). Directions must be
  // on the upper hemisphere (not checked here: the decoder checks its inputs).
  std::vector<ImageWeight> weights(const Direction& light, const Direction& view) const;
  // The same for unit vectors (z = the surface normal).
  std::vector<ImageWeight> weights(const std::array<double, 3>& light, const std::array<double, 3>& view) const;

 private:
  std::vector<std::array<double, 3>> lights_, views_;
  std::vector<std::uint8_t> usable_;  // empty = all
};

// The mean (3 floats) and basis (3 rows of C floats) at a query: sum_i w_i x row(image_i).
// Accumulated in double; a single weight of 1 copies the stored rows bit for bit.
void combinePcaRows(const float* mean, const float* basis, int components, const std::vector<ImageWeight>& weights,
                    float* meanOut, float* basisOut);

// One texel: rgb[c] = mean3[c] + coefficients . basis3[c] (normalized: linear / alpha).
// The single definition every decoder path uses, so all of them agree bit for bit.
void pcaTexelValue(const float* coefficients, const float* mean3, const float* basis3, int components, float* rgb);

}  // namespace nbtf
