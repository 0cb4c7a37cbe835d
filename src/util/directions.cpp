#include "util/directions.h"

#include <cmath>
#include <limits>
#include <sstream>

#include "util/error.h"

namespace nbtf {
namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;
}  // namespace

std::array<double, 3> Direction::unitVector() const {
  double t = thetaDeg * kDeg, p = phiDeg * kDeg;
  return {std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t)};
}

Direction Direction::fromUnitVector(double x, double y, double z) {
  double n = std::sqrt(x * x + y * y + z * z);
  if (!(n > 0)) throw Error("direction vector has zero length");
  x /= n, y /= n, z /= n;
  Direction d;
  d.thetaDeg = std::acos(std::max(-1.0, std::min(1.0, z))) / kDeg;
  d.phiDeg = std::atan2(y, x) / kDeg;
  if (d.phiDeg < 0) d.phiDeg += 360.0;
  return d;
}

void checkHemisphere(const Direction& d, const std::string& what) {
  if (!std::isfinite(d.thetaDeg) || !std::isfinite(d.phiDeg))
    throw Error(what + " direction is not finite");
  if (d.thetaDeg < 0 || d.thetaDeg > 90) {
    std::ostringstream s;
    s << what << " direction theta = " << d.thetaDeg
      << " degrees is outside the upper hemisphere (0 <= theta <= 90)";
    throw Error(s.str());
  }
}

const std::vector<Direction>& hemisphere81() {
  static const std::vector<Direction> dirs = [] {
    std::vector<Direction> out;
    const int counts[] = {1, 6, 12, 18, 20, 24};
    for (int ring = 0; ring < 6; ++ring) {
      for (int i = 0; i < counts[ring]; ++i) out.push_back({15.0 * ring, 360.0 * i / counts[ring]});
    }
    return out;
  }();
  return dirs;
}

std::array<float, 2> stereographic(const Direction& d) {
  double t = kPi - d.thetaDeg * kDeg;
  double denom = 1.0 - std::cos(t);
  double r = std::sin(t) / denom;  // denom >= 1 on the upper hemisphere
  double p = d.phiDeg * kDeg;
  return {static_cast<float>(r * std::cos(p)), static_cast<float>(r * std::sin(p))};
}

Direction parseDirection(const std::string& text, const std::string& what) {
  std::istringstream in(text);
  Direction d;
  char comma = 0;
  if (!(in >> d.thetaDeg >> comma >> d.phiDeg) || comma != ',' || !(in >> std::ws).eof())
    throw Error(what + ": expected THETA,PHI in degrees, got '" + text + "'");
  checkHemisphere(d, what);
  return d;
}

int nearestDirection(const std::vector<Direction>& set, const Direction& d) {
  auto v = d.unitVector();
  int best = -1;
  double bestDot = -std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < set.size(); ++i) {
    auto u = set[i].unitVector();
    double dot = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    if (dot > bestDot) bestDot = dot, best = static_cast<int>(i);
  }
  return best;
}

}  // namespace nbtf
