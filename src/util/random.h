// The project's random numbers: fully specified, so a seed gives the same draws on every
// platform and standard library (std::*_distribution does not promise that).
//
// One engine, SplitMix64, serves training (sampling, hold-out split) and the synthetic
// materials (data_tools/synth). The cluster stage's draws (k-means++ seeding, randomized PCA)
// come from std::mt19937_64 through StageRandom: that engine is fully specified by the
// standard too, and changing it would change every clustering and so every file a seed has
// ever produced (the bit-identity the tests and users rely on).
#pragma once
#include <cmath>
#include <cstdint>
#include <random>

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
  // Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  static std::uint64_t mix(std::uint64_t a, std::uint64_t b) {
    SplitMix64 r(a ^ (b * 0xd1342543de82ef95ull + 0x2545f4914f6cdd1dull));
    r.next();
    return r.next();
  }

 private:
  std::uint64_t state_;
};

// The cluster stage's draws (see above).
class StageRandom {
 public:
  explicit StageRandom(std::uint64_t seed) : engine_(seed) {}
  // Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  // Uniform integer in [0, n).
  std::uint64_t below(std::uint64_t n) { return static_cast<std::uint64_t>(uniform() * n) % n; }
  // Standard normal (Box-Muller; the second value of each pair is kept for the next call).
  double normal() {
    if (hasSpare_) {
      hasSpare_ = false;
      return spare_;
    }
    double u1 = 1.0 - uniform(), u2 = uniform();  // u1 in (0, 1]: log is finite
    double r = std::sqrt(-2.0 * std::log(u1)), a = 6.283185307179586 * u2;
    spare_ = r * std::sin(a);
    hasSpare_ = true;
    return r * std::cos(a);
  }

 private:
  std::mt19937_64 engine_;
  double spare_ = 0;
  bool hasSpare_ = false;
};

}  // namespace nbtf
