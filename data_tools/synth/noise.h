// Seeded randomness and tileable noise for the synthetic materials. Every random
// quantity of a material is drawn from one Rng in a fixed order at construction, so a
// material depends on (preset, size, seed) only - never on thread count or timing.
// All noise is periodic on an integer lattice, so a pattern whose lattice periods
// divide the image tiles without seams.
#pragma once
#include <cstdint>
#include <vector>

#include "util/random.h"

namespace nbtf::synth {

// The project's SplitMix64 (util/random.h) with the draws procedural textures use.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : engine_(seed) {}
  std::uint64_t next() { return engine_.next(); }
  double uniform() { return engine_.uniform(); }  // [0, 1)
  double uniform(double lo, double hi);       // [lo, hi)
  double symmetric() { return uniform(-1.0, 1.0); }
  int below(int n);                           // [0, n)
  // A child generator for an independent stream (so adding draws to one part of a
  // pattern does not shift the random numbers of another).
  Rng fork();

 private:
  SplitMix64 engine_;
};

// Value noise on a periodX x periodY lattice with quintic interpolation, values in
// about [-1, 1]. eval(u, v) takes lattice coordinates; it wraps at the periods.
class PeriodicNoise {
 public:
  PeriodicNoise() = default;
  PeriodicNoise(Rng& rng, int periodX, int periodY);
  float eval(double u, double v) const;
  int periodX() const { return px_; }
  int periodY() const { return py_; }

 private:
  int px_ = 1, py_ = 1;
  std::vector<float> lattice_;
};

// Sum of `octaves` PeriodicNoise layers, each with doubled periods and `gain` times the
// amplitude; eval takes coordinates in units of the first layer's lattice. Normalized so
// the amplitude weights sum to 1.
class PeriodicFbm {
 public:
  PeriodicFbm() = default;
  PeriodicFbm(Rng& rng, int periodX, int periodY, int octaves, double gain = 0.5);
  float eval(double u, double v) const;
  int periodX() const { return layers_.empty() ? 1 : layers_[0].periodX(); }
  int periodY() const { return layers_.empty() ? 1 : layers_[0].periodY(); }

 private:
  std::vector<PeriodicNoise> layers_;
  std::vector<float> weights_;
};

// Worley (cellular) noise on a periodic grid of cells, one jittered feature point per
// cell. eval returns the distances to the nearest and second-nearest points, in cell units.
class PeriodicCells {
 public:
  PeriodicCells() = default;
  PeriodicCells(Rng& rng, int cellsX, int cellsY, double jitter = 0.8);
  void eval(double u, double v, float& f1, float& f2, int& nearestCell) const;
  int cellsX() const { return cx_; }
  int cellsY() const { return cy_; }

 private:
  int cx_ = 1, cy_ = 1;
  std::vector<float> points_;  // 2 per cell: offset inside the cell
};

// Wraps i into [0, n).
inline int wrapIndex(int i, int n) {
  int r = i % n;
  return r < 0 ? r + n : r;
}

}  // namespace nbtf::synth
