#include "synth/noise.h"

#include <cmath>
#include <limits>

namespace nbtf::synth {

// ---- Rng ---------------------------------------------------------------------------

double Rng::uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }

int Rng::below(int n) { return static_cast<int>(uniform() * n); }

Rng Rng::fork() { return Rng(next() ^ 0xD1B54A32D192ED03ull); }

// ---- Value noise -----------------------------------------------------------------

namespace {
inline double fade(double t) { return t * t * t * (t * (t * 6 - 15) + 10); }
}  // namespace

PeriodicNoise::PeriodicNoise(Rng& rng, int periodX, int periodY)
    : px_(periodX < 1 ? 1 : periodX), py_(periodY < 1 ? 1 : periodY) {
  lattice_.resize(static_cast<std::size_t>(px_) * py_);
  for (float& v : lattice_) v = static_cast<float>(rng.symmetric());
}

float PeriodicNoise::eval(double u, double v) const {
  double fu = std::floor(u), fv = std::floor(v);
  int x0 = wrapIndex(static_cast<int>(fu), px_), y0 = wrapIndex(static_cast<int>(fv), py_);
  int x1 = x0 + 1 == px_ ? 0 : x0 + 1, y1 = y0 + 1 == py_ ? 0 : y0 + 1;
  double tx = fade(u - fu), ty = fade(v - fv);
  const float* row0 = lattice_.data() + static_cast<std::size_t>(y0) * px_;
  const float* row1 = lattice_.data() + static_cast<std::size_t>(y1) * px_;
  double a = row0[x0] + (row0[x1] - row0[x0]) * tx;
  double b = row1[x0] + (row1[x1] - row1[x0]) * tx;
  return static_cast<float>(a + (b - a) * ty);
}

PeriodicFbm::PeriodicFbm(Rng& rng, int periodX, int periodY, int octaves, double gain) {
  double amplitude = 1, total = 0;
  for (int o = 0; o < octaves; ++o) {
    layers_.emplace_back(rng, periodX << o, periodY << o);
    weights_.push_back(static_cast<float>(amplitude));
    total += amplitude;
    amplitude *= gain;
  }
  for (float& w : weights_) w = static_cast<float>(w / total);
}

float PeriodicFbm::eval(double u, double v) const {
  float sum = 0;
  double scale = 1;
  for (std::size_t o = 0; o < layers_.size(); ++o, scale *= 2) sum += weights_[o] * layers_[o].eval(u * scale, v * scale);
  return sum;
}

// ---- Cellular noise ----------------------------------------------------------------

PeriodicCells::PeriodicCells(Rng& rng, int cellsX, int cellsY, double jitter)
    : cx_(cellsX < 1 ? 1 : cellsX), cy_(cellsY < 1 ? 1 : cellsY) {
  points_.resize(static_cast<std::size_t>(cx_) * cy_ * 2);
  for (float& p : points_) p = static_cast<float>(0.5 + 0.5 * jitter * rng.symmetric());
}

void PeriodicCells::eval(double u, double v, float& f1, float& f2, int& nearestCell) const {
  int ix = static_cast<int>(std::floor(u)), iy = static_cast<int>(std::floor(v));
  double best = std::numeric_limits<double>::infinity(), second = best;
  nearestCell = 0;
  for (int dy = -2; dy <= 2; ++dy) {
    for (int dx = -2; dx <= 2; ++dx) {
      int cell = wrapIndex(iy + dy, cy_) * cx_ + wrapIndex(ix + dx, cx_);
      double px = ix + dx + points_[2 * cell], py = iy + dy + points_[2 * cell + 1];
      double d2 = (px - u) * (px - u) + (py - v) * (py - v);
      if (d2 < best) {
        second = best, best = d2, nearestCell = cell;
      } else if (d2 < second) {
        second = d2;
      }
    }
  }
  f1 = static_cast<float>(std::sqrt(best));
  f2 = static_cast<float>(std::sqrt(second));
}

}  // namespace nbtf::synth
