// Forward-mode automatic differentiation with two tangents: a value and its partial
// derivatives with respect to the image-plane position (x, y) of the pixel a ray goes
// through (the adaptive-oversampling paper, eq. 5-6). Every operation applies the chain rule once, so any
// computation written over `Dual` carries d/dx and d/dy along with its value.
//
// The renderer's geometry is written once as templates over the scalar type: `double`
// for plain rays, `Dual` for rays with derivatives (val(), dx() and dy() work on both).
#pragma once
#include <algorithm>
#include <array>
#include <cmath>

namespace nbtf {

struct Dual {
  double v = 0, dx = 0, dy = 0;
  Dual() = default;
  Dual(double value) : v(value) {}  // a constant: zero derivatives  NOLINT(implicit)
  Dual(double value, double ddx, double ddy) : v(value), dx(ddx), dy(ddy) {}
};

inline Dual operator+(const Dual& a, const Dual& b) { return {a.v + b.v, a.dx + b.dx, a.dy + b.dy}; }
inline Dual operator-(const Dual& a, const Dual& b) { return {a.v - b.v, a.dx - b.dx, a.dy - b.dy}; }
inline Dual operator-(const Dual& a) { return {-a.v, -a.dx, -a.dy}; }
inline Dual operator*(const Dual& a, const Dual& b) {
  return {a.v * b.v, a.dx * b.v + a.v * b.dx, a.dy * b.v + a.v * b.dy};
}
inline Dual operator/(const Dual& a, const Dual& b) {
  const double inv = 1.0 / b.v, q = a.v * inv;
  return {q, (a.dx - q * b.dx) * inv, (a.dy - q * b.dy) * inv};
}
inline Dual& operator+=(Dual& a, const Dual& b) { return a = a + b; }
inline Dual& operator-=(Dual& a, const Dual& b) { return a = a - b; }
inline Dual& operator*=(Dual& a, const Dual& b) { return a = a * b; }
inline Dual& operator/=(Dual& a, const Dual& b) { return a = a / b; }
// Comparisons look at the value only (the branch taken at the ray itself).
inline bool operator<(const Dual& a, const Dual& b) { return a.v < b.v; }
inline bool operator>(const Dual& a, const Dual& b) { return a.v > b.v; }
inline bool operator<=(const Dual& a, const Dual& b) { return a.v <= b.v; }
inline bool operator>=(const Dual& a, const Dual& b) { return a.v >= b.v; }

inline Dual sqrt(const Dual& a) {
  const double s = std::sqrt(a.v);
  const double k = s > 0 ? 0.5 / s : 0.0;
  return {s, a.dx * k, a.dy * k};
}
inline Dual exp(const Dual& a) {
  const double e = std::exp(a.v);
  return {e, a.dx * e, a.dy * e};
}
inline Dual sin(const Dual& a) {
  const double c = std::cos(a.v);
  return {std::sin(a.v), a.dx * c, a.dy * c};
}
inline Dual cos(const Dual& a) {
  const double s = -std::sin(a.v);
  return {std::cos(a.v), a.dx * s, a.dy * s};
}
inline Dual atan2(const Dual& y, const Dual& x) {
  const double r2 = x.v * x.v + y.v * y.v;
  const double k = r2 > 0 ? 1.0 / r2 : 0.0;
  return {std::atan2(y.v, x.v), (x.v * y.dx - y.v * x.dx) * k, (x.v * y.dy - y.v * x.dy) * k};
}
inline Dual acos(const Dual& a) {
  const double c = std::clamp(a.v, -1.0, 1.0);
  const double s = std::sqrt(std::max(1e-300, 1.0 - c * c));
  return {std::acos(c), -a.dx / s, -a.dy / s};
}
inline Dual abs(const Dual& a) { return a.v < 0 ? -a : a; }

// Uniform access for templates over double and Dual.
inline double val(double a) { return a; }
inline double val(const Dual& a) { return a.v; }
inline double dx(double) { return 0; }
inline double dx(const Dual& a) { return a.dx; }
inline double dy(double) { return 0; }
inline double dy(const Dual& a) { return a.dy; }

// First-order range of `a` over a pixel footprint of half-width `half` (pixel units): the
// extremes of a + sx dx + sy dy for |sx|, |sy| <= half, reached at the footprint's corners.
inline double spread(const Dual& a, double half) { return half * (std::fabs(a.dx) + std::fabs(a.dy)); }
// Whether `a`, extrapolated to the footprint's corners and edge midpoints (the 8 points of the
// adaptive-oversampling paper), may reach `level` from the side its centre value is on: the
// centre's test (a < level or a >= level) may change inside the footprint.
inline bool mayCross(const Dual& a, double level, double half) {
  const double s = spread(a, half);
  return a.v - s <= level && a.v + s >= level;
}
// The value at footprint offset (ox, oy) pixels, to first order.
inline double extrapolate(const Dual& a, double ox, double oy) { return a.v + ox * a.dx + oy * a.dy; }
inline double extrapolate(double a, double, double) { return a; }

// ---- 3-vectors over double or Dual
template <class T>
struct Vec3 {
  T x{}, y{}, z{};
  Vec3() = default;
  Vec3(T x_, T y_, T z_) : x(x_), y(y_), z(z_) {}
  template <class U>
  explicit Vec3(const Vec3<U>& o) : x(o.x), y(o.y), z(o.z) {}
};
using Vec3d = Vec3<double>;
using Vec3D = Vec3<Dual>;

template <class T, class U>
auto operator+(const Vec3<T>& a, const Vec3<U>& b) {
  using R = decltype(a.x + b.x);
  return Vec3<R>(a.x + b.x, a.y + b.y, a.z + b.z);
}
template <class T, class U>
auto operator-(const Vec3<T>& a, const Vec3<U>& b) {
  using R = decltype(a.x - b.x);
  return Vec3<R>(a.x - b.x, a.y - b.y, a.z - b.z);
}
template <class T>
Vec3<T> operator-(const Vec3<T>& a) {
  return Vec3<T>(-a.x, -a.y, -a.z);
}
template <class T, class S>
auto operator*(const Vec3<T>& a, const S& s) {
  using R = decltype(a.x * s);
  return Vec3<R>(a.x * s, a.y * s, a.z * s);
}
template <class T, class S>
auto operator*(const S& s, const Vec3<T>& a) {
  return a * s;
}
template <class T, class U>
auto dot(const Vec3<T>& a, const Vec3<U>& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
template <class T, class U>
auto cross(const Vec3<T>& a, const Vec3<U>& b) {
  using R = decltype(a.x * b.x);
  return Vec3<R>(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
template <class T>
T length(const Vec3<T>& a) {
  using std::sqrt;
  return sqrt(dot(a, a));
}
template <class T>
Vec3<T> normalize(const Vec3<T>& a) {
  const T inv = T(1.0) / length(a);
  return Vec3<T>(a.x * inv, a.y * inv, a.z * inv);
}
inline Vec3d val(const Vec3d& a) { return a; }
inline Vec3d val(const Vec3D& a) { return {a.x.v, a.y.v, a.z.v}; }
// First-order value of a dual vector at footprint offset (ox, oy).
inline Vec3d extrapolate(const Vec3D& a, double ox, double oy) {
  return {extrapolate(a.x, ox, oy), extrapolate(a.y, ox, oy), extrapolate(a.z, ox, oy)};
}
inline Vec3d extrapolate(const Vec3d& a, double, double) { return a; }

}  // namespace nbtf
