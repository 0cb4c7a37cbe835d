// Helpers shared by the pattern families.
#include <algorithm>
#include <cmath>

#include "synth/meso_pattern.h"

namespace nbtf::synth {
namespace {
constexpr double kPi = 3.14159265358979323846;
}

int repeatsAcross(int size, double pitch, int multiple) {
  multiple = std::max(1, multiple);
  int groups = static_cast<int>(std::lround(size / pitch / multiple));
  return std::max(1, groups) * multiple;
}

float smoothstep(float edge0, float edge1, float x) {
  float t = std::clamp((x - edge0) / (edge1 - edge0), 0.0f, 1.0f);
  return t * t * (3 - 2 * t);
}

PlyResult plyRidges(const double rel[2], const double axis[2], double twistDeg, double spacing, double tileLength) {
  const double perp[2] = {-axis[1], axis[0]};
  double along = rel[0] * axis[0] + rel[1] * axis[1];
  double across = rel[0] * perp[0] + rel[1] * perp[1];
  double a = twistDeg * kPi / 180;
  // Ridges of constant phase along/alongPeriod - across/acrossPeriod run at the twist angle.
  bool twisted = std::fabs(std::sin(a)) > 1e-6;
  double alongPeriod = twisted ? spacing / std::sin(a) : 1e9;
  if (twisted && tileLength > 0 && alongPeriod < tileLength)
    alongPeriod = tileLength / std::max(1.0, std::round(tileLength / alongPeriod));
  double acrossPeriod = spacing / std::cos(a);
  double phase = (twisted ? along / alongPeriod : 0.0) - across / acrossPeriod;
  PlyResult r;
  r.ridge = static_cast<float>(std::cos(2 * kPi * phase));
  // Direction of constant phase: (alongPeriod, acrossPeriod) in the yarn frame.
  double ta = alongPeriod, tc = acrossPeriod, n = std::hypot(ta, tc);
  ta /= n, tc /= n;
  r.tangent[0] = static_cast<float>(ta * axis[0] + tc * perp[0]);
  r.tangent[1] = static_cast<float>(ta * axis[1] + tc * perp[1]);
  return r;
}

}  // namespace nbtf::synth
