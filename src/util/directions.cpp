#include "util/directions.h"

#include <cmath>
#include <cstdio>
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

bool isDirectionEncoding(int code) { return code >= 1 && code <= 4; }

int fourierOctaves(DirectionEncoding encoding) {
  if (encoding == DirectionEncoding::StereographicFourier) return 3;
  return encoding == DirectionEncoding::StereographicFourier2 ? 2 : 0;
}

int directionInputCount(DirectionEncoding encoding) {
  if (encoding == DirectionEncoding::StereographicHalf) return 8;
  return 4 + 4 * 2 * fourierOctaves(encoding);
}

std::string directionEncodingName(DirectionEncoding encoding) {
  switch (encoding) {
    case DirectionEncoding::StereographicHalf: return "stereographic+half";
    case DirectionEncoding::StereographicFourier: return "stereographic+fourier";
    case DirectionEncoding::StereographicFourier2: return "stereographic+fourier2";
    default: return "stereographic";
  }
}

std::string directionEncodingDescription(DirectionEncoding encoding) {
  const std::string base = "stereographic projection (eq. 7-9), light then view";
  const std::string inputs = std::to_string(directionInputCount(encoding)) + " inputs)";
  if (encoding == DirectionEncoding::StereographicHalf)
    return base + ", + half vector and cos(theta_d) (stereographic+half, " + inputs;
  if (fourierOctaves(encoding) > 0)
    return base + ", + sin and cos of each at " + std::to_string(fourierOctaves(encoding)) + " octaves (" +
           directionEncodingName(encoding) + ", " + inputs;
  return base + " (" + inputs;
}

std::vector<DirectionEncoding> directionEncodings() {
  std::vector<DirectionEncoding> all;
  for (int code = 1; isDirectionEncoding(code); ++code) all.push_back(static_cast<DirectionEncoding>(code));
  return all;
}

DirectionEncoding parseDirectionEncoding(const std::string& name) {
  std::string expected;
  for (DirectionEncoding encoding : directionEncodings()) {
    if (name == directionEncodingName(encoding)) return encoding;
    expected += (expected.empty() ? "\"" : ", \"") + directionEncodingName(encoding) + "\"";
  }
  throw Error("unknown direction encoding \"" + name + "\" (expected one of " + expected + ")");
}

namespace {
// tan(theta / 2) (cos phi, sin phi) = (x, y) / (1 + z): eq. (7)-(9) of the paper for a unit vector.
void stereographicOfUnit(const std::array<double, 3>& u, float* out) {
  out[0] = static_cast<float>(u[0] / (1 + u[2]));
  out[1] = static_cast<float>(u[1] / (1 + u[2]));
}

// The half-vector inputs of StereographicHalf (4 values) from unit light and view vectors.
void halfVectorInputs(const std::array<double, 3>& light, const std::array<double, 3>& view, float* out) {
  double h[3] = {light[0] + view[0], light[1] + view[1], light[2] + view[2]};
  const double n = std::sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);  // > 0: both on the upper hemisphere
  for (double& c : h) c = n > 0 ? c / n : 0;
  if (!(n > 0)) h[2] = 1;
  out[0] = static_cast<float>(h[0]);
  out[1] = static_cast<float>(h[1]);
  out[2] = static_cast<float>(h[2]);
  out[3] = static_cast<float>(light[0] * h[0] + light[1] * h[1] + light[2] * h[2]);
}

// sin and cos of 2^o pi c for o = 0 .. octaves - 1. Only octave 0 calls libm; each
// higher octave doubles the angle (sin 2a = 2 sin a cos a, cos 2a = cos^2 a - sin^2 a), a few
// double ulps from the direct sin and cos, far below the float the inputs are stored in. A
// query brings its own directions, so this is per query: 8 libm calls instead of 8 per octave.
void fourierInputs(const float* stereo, int octaves, float* out) {
  for (int c = 0; c < 4; ++c) {
    const double a = kPi * stereo[c];
    double s = std::sin(a), co = std::cos(a);
    for (int o = 0; o < octaves; ++o) {
      *out++ = static_cast<float>(s);
      *out++ = static_cast<float>(co);
      const double s2 = 2 * s * co, c2 = co * co - s * s;
      s = s2, co = c2;
    }
  }
}
}  // namespace

void encodeDirections(DirectionEncoding encoding, const std::array<double, 3>& light, const std::array<double, 3>& view,
                      float* out) {
  stereographicOfUnit(light, out);
  stereographicOfUnit(view, out + 2);
  if (encoding == DirectionEncoding::StereographicHalf) halfVectorInputs(light, view, out + 4);
  if (fourierOctaves(encoding) > 0) fourierInputs(out, fourierOctaves(encoding), out + 4);
}

void encodeDirections(DirectionEncoding encoding, const Direction& light, const Direction& view, float* out) {
  auto l = stereographic(light), v = stereographic(view);
  out[0] = l[0], out[1] = l[1], out[2] = v[0], out[3] = v[1];  // the paper's formula, as trained before
  if (encoding == DirectionEncoding::StereographicHalf) halfVectorInputs(light.unitVector(), view.unitVector(), out + 4);
  if (fourierOctaves(encoding) > 0) fourierInputs(out, fourierOctaves(encoding), out + 4);
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

std::string formatDirection(const Direction& d) {
  auto angle = [](double deg) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", std::round(deg * 1000) / 1000);
    return std::string(buf);
  };
  return "(" + angle(d.thetaDeg) + "\xC2\xB0, " + angle(d.phiDeg) + "\xC2\xB0)";
}

bool sameDirection(const Direction& a, const Direction& b) {
  auto u = a.unitVector(), v = b.unitVector();
  double dot = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
  return dot > std::cos(1e-3 * 3.14159265358979323846 / 180);
}

void checkSameDirections(const std::vector<Direction>& ref, const std::vector<Direction>& file, const char* what,
                         const std::string& prefix) {
  if (ref.size() != file.size())
    throw Error(prefix + "the reference has " + std::to_string(ref.size()) + " " + what + " directions, the file " +
                std::to_string(file.size()));
  for (std::size_t i = 0; i < ref.size(); ++i)
    if (!sameDirection(ref[i], file[i]))
      throw Error(prefix + what + " direction " + std::to_string(i) + " is " + formatDirection(ref[i]) +
                  " in the reference but " + formatDirection(file[i]) + " in the file");
}

}  // namespace nbtf
