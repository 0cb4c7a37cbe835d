// Shared by the dense kernel tests (float and bfloat16 products): random operands, a relative
// error against a double reference, and the product shapes.
#pragma once
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace nbtf::detail::kernel_test {

inline std::vector<float> randomValues(std::size_t n, std::mt19937& rng) {
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float> v(n);
  for (float& x : v) x = u(rng);
  return v;
}

// Largest |a - b| relative to the largest |b| (b: a double reference).
inline double relativeError(const float* a, const std::vector<double>& b) {
  double err = 0, scale = 1e-30;
  for (std::size_t i = 0; i < b.size(); ++i) {
    err = std::max(err, std::abs(a[i] - b[i]));
    scale = std::max(scale, std::abs(b[i]));
  }
  return err / scale;
}

// A product's rows, its sum's depth, its columns and the left-hand side's row stride.
struct Shape {
  int n, k, cols, ld;
};

}  // namespace nbtf::detail::kernel_test
