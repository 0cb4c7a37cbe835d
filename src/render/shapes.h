// Analytic shapes and their ray intersections, written once over the scalar type (double
// for plain rays, Dual for rays with derivatives; render/dual.h).
//
// With Dual rays every routine also applies the adaptive-oversampling paper's test (sections 3.1-3.2):
// each condition that decides hit or miss (a discriminant's sign, a coordinate inside its
// bounds, a depth against t_min) is extrapolated to the corners of the pixel footprint
// (EdgeProbe::half pixels around the ray); if its outcome may change there, the footprint
// may straddle a silhouette and EdgeProbe::edge is set. For the height field ("cloth"),
// whose hit is found by marching, the derivatives of the hit come from the implicit
// function theorem (one Newton step in Dual arithmetic at the converged t) and a near miss
// is tested on the smallest vertical gap between ray and surface (its derivative is the
// partial derivative at the minimizing t, by the envelope theorem).
//
// Texture coordinates (u, v) are in textures: u = 1 is one copy of the material (the
// decoder's convention: texel x = floor(u * width) mod width; v grows with the image rows).
#pragma once
#include <algorithm>
#include <cmath>
#include <limits>

#include "render/camera.h"
#include "render/dual.h"

namespace nbtf {

inline bool mayCross(double, double, double) { return false; }
inline double spread(double, double) { return 0; }

enum class ShapeKind { Sphere, Rect, Cylinder, Cloth };

struct Shape {
  ShapeKind kind = ShapeKind::Sphere;
  int material = 0;       // 0: the BTF, 1: grey diffuse
  double tiling = 1;      // copies of the texture per unit of the shape's parametrization (see below)
  // Sphere: centre, radius. u = tiling * phi / 2pi (phi = atan2(z, x) about the centre),
  // v = tiling * theta / 2pi (theta from +y), so texels are square on the equator.
  // Cylinder (axis +y through centre.x, centre.z; y in [y0, y1]; open, two-sided):
  // u = tiling * phi / 2pi, v = tiling * (y1 - y) / (2 pi radius).
  Vec3d center{0, 0, 0};
  double radius = 1;
  double y0 = 0, y1 = 1;
  // Rect: centre + s1 e1 + s2 e2, |s1| <= a1, |s2| <= a2 (e1, e2 orthonormal; normal e1 x e2,
  // two-sided). u = tiling * (s1 + a1) / (2 a1), v = tiling * (s2 + a2) / (2 a1).
  Vec3d e1{1, 0, 0}, e2{0, 0, 1};
  double a1 = 1, a2 = 1;
  // Cloth: the height field y = clothHeight(x, z) over |x|, |z| <= a1 (a draped sheet:
  // a Gaussian bump with folds); u = tiling * (x + a1) / (2 a1), v = tiling * (z + a1) / (2 a1).
};

template <class T>
struct SurfaceHit {
  T t{};
  Vec3<T> p, n;  // point, unit geometric normal (outward / the shape's own side)
  Vec3<T> tu;    // tangent along increasing u (not normalized)
  T u{}, v{};    // texture coordinates (textures)
};

// The footprint test's input and output (Dual rays only).
struct EdgeProbe {
  double half = 0.5;  // footprint half-width in pixels
  bool edge = false;
  double depth = std::numeric_limits<double>::infinity();  // nearest ray parameter of a flagged event
  void flag(double t) {
    edge = true;
    depth = std::min(depth, t);
  }
};

// ---- The cloth height field and its slopes.
template <class T>
T clothHeight(const T& x, const T& z) {
  using std::exp;
  using std::sin;
  const T g = exp((x * x + z * z) * (-1.0 / 0.45));
  return 0.12 + 0.8 * g + 0.06 * sin(5.0 * x + 2.0 * z) * (1.0 - g);
}
template <class T>
void clothSlope(const T& x, const T& z, T& hx, T& hz) {
  using std::cos;
  using std::exp;
  using std::sin;
  const T g = exp((x * x + z * z) * (-1.0 / 0.45));
  const T gx = g * x * (-2.0 / 0.45), gz = g * z * (-2.0 / 0.45);
  const T s = sin(5.0 * x + 2.0 * z), c = cos(5.0 * x + 2.0 * z);
  hx = 0.8 * gx + 0.06 * (5.0 * c * (1.0 - g) - s * gx);
  hz = 0.8 * gz + 0.06 * (2.0 * c * (1.0 - g) - s * gz);
}
constexpr double kClothMinY = 0.0, kClothMaxY = 1.0;  // bounds of clothHeight

namespace detail {

template <class T>
bool intersectSphere(const Shape& s, const Ray<T>& ray, double tmin, double tmax, SurfaceHit<T>* hit, EdgeProbe* probe) {
  using std::atan2;
  using std::acos;
  using std::sqrt;
  const Vec3<T> oc = ray.origin - s.center;
  const T b = dot(oc, ray.dir);  // a = 1 (unit direction), half b
  const T c = dot(oc, oc) - s.radius * s.radius;
  const T disc = b * b - c;
  if (probe && mayCross(disc, 0.0, probe->half) && -val(b) > tmin) probe->flag(-val(b));
  if (val(disc) < 0) return false;
  const T root = sqrt(disc);
  T t = -b - root;
  if (val(t) <= tmin) {
    if (probe && mayCross(t, tmin, probe->half)) probe->flag(val(t));
    t = -b + root;
    if (val(t) <= tmin) {
      if (probe && mayCross(t, tmin, probe->half)) probe->flag(val(t));
      return false;
    }
  }
  if (val(t) >= tmax) return false;
  if (hit) {
    hit->t = t;
    hit->p = ray.origin + ray.dir * t;
    const Vec3<T> q = hit->p - s.center;
    hit->n = q * (1.0 / s.radius);
    const T phi = atan2(q.z, q.x);
    const T theta = acos(q.y * (1.0 / s.radius));
    hit->u = phi * (s.tiling / (2 * M_PI));
    hit->v = theta * (s.tiling / (2 * M_PI));
    hit->tu = Vec3<T>(-q.z, T(0.0), q.x);  // d p / d phi
  }
  return true;
}

template <class T>
bool intersectRect(const Shape& s, const Ray<T>& ray, double tmin, double tmax, SurfaceHit<T>* hit, EdgeProbe* probe) {
  const Vec3d n = cross(s.e1, s.e2);
  const T dn = dot(ray.dir, n);
  if (std::fabs(val(dn)) < 1e-12) return false;
  const T t = dot(s.center - ray.origin, n) / dn;
  if (val(t) >= tmax) return false;
  const Vec3<T> p = ray.origin + ray.dir * t;
  const T s1 = dot(p - s.center, s.e1), s2 = dot(p - s.center, s.e2);
  if (probe && val(t) > 0 &&
      (mayCross(s1, -s.a1, probe->half) || mayCross(s1, s.a1, probe->half) || mayCross(s2, -s.a2, probe->half) ||
       mayCross(s2, s.a2, probe->half) || mayCross(t, tmin, probe->half)))
    probe->flag(val(t));
  if (val(t) <= tmin || std::fabs(val(s1)) > s.a1 || std::fabs(val(s2)) > s.a2) return false;
  if (hit) {
    hit->t = t;
    hit->p = p;
    hit->n = Vec3<T>(n);
    hit->u = (s1 + s.a1) * (s.tiling / (2 * s.a1));
    hit->v = (s2 + s.a2) * (s.tiling / (2 * s.a1));
    hit->tu = Vec3<T>(s.e1);
  }
  return true;
}

template <class T>
bool intersectCylinder(const Shape& s, const Ray<T>& ray, double tmin, double tmax, SurfaceHit<T>* hit, EdgeProbe* probe) {
  using std::atan2;
  using std::sqrt;
  const T ox = ray.origin.x - s.center.x, oz = ray.origin.z - s.center.z;
  const T a = ray.dir.x * ray.dir.x + ray.dir.z * ray.dir.z;
  if (val(a) < 1e-14) return false;  // parallel to the axis
  const T b = ox * ray.dir.x + oz * ray.dir.z;  // half b
  const T c = ox * ox + oz * oz - s.radius * s.radius;
  const T disc = b * b - a * c;
  if (probe && mayCross(disc, 0.0, probe->half) && -val(b) / val(a) > tmin) probe->flag(-val(b) / val(a));
  if (val(disc) < 0) return false;
  const T root = sqrt(disc);
  const T roots[2] = {(-b - root) / a, (-b + root) / a};
  bool found = false;
  T t{};
  for (const T& r : roots) {
    if (val(r) >= tmax) break;
    const T y = ray.origin.y + ray.dir.y * r;
    if (probe && val(r) > 0 &&
        (mayCross(y, s.y0, probe->half) || mayCross(y, s.y1, probe->half) || mayCross(r, tmin, probe->half)))
      probe->flag(val(r));
    if (val(r) > tmin && val(y) >= s.y0 && val(y) <= s.y1) {
      t = r;
      found = true;
      break;
    }
  }
  if (!found) return false;
  if (hit) {
    hit->t = t;
    hit->p = ray.origin + ray.dir * t;
    const T qx = hit->p.x - s.center.x, qz = hit->p.z - s.center.z;
    hit->n = Vec3<T>(qx * (1.0 / s.radius), T(0.0), qz * (1.0 / s.radius));
    hit->u = atan2(qz, qx) * (s.tiling / (2 * M_PI));
    hit->v = (s.y1 - hit->p.y) * (s.tiling / (2 * M_PI * s.radius));
    hit->tu = Vec3<T>(-qz, T(0.0), qx);
  }
  return true;
}

// Ray parameter interval inside the axis-aligned box [lo, hi]; false when empty.
inline bool clipToBox(const Vec3d& o, const Vec3d& d, const Vec3d& lo, const Vec3d& hi, double& t0, double& t1) {
  const double os[3] = {o.x, o.y, o.z}, ds[3] = {d.x, d.y, d.z}, los[3] = {lo.x, lo.y, lo.z}, his[3] = {hi.x, hi.y, hi.z};
  for (int i = 0; i < 3; ++i) {
    if (std::fabs(ds[i]) < 1e-15) {
      if (os[i] < los[i] || os[i] > his[i]) return false;
      continue;
    }
    double a = (los[i] - os[i]) / ds[i], b = (his[i] - os[i]) / ds[i];
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
  }
  return t0 <= t1;
}

template <class T>
T clothGap(const Ray<T>& ray, const T& t) {
  const T x = ray.origin.x + ray.dir.x * t, z = ray.origin.z + ray.dir.z * t;
  return ray.origin.y + ray.dir.y * t - clothHeight(x, z);
}

constexpr int kClothSamples = 64;

template <class T>
bool intersectCloth(const Shape& s, const Ray<T>& ray, double tmin, double tmax, SurfaceHit<T>* hit, EdgeProbe* probe) {
  const Ray<double> r{val(ray.origin), val(ray.dir)};
  // March over a box a little wider than the sheet, so a tentative hit just outside its
  // border is found too (the adaptive-oversampling paper, 3.5) and the border can be tested as an edge.
  const double A = s.a1, margin = 0.25 * s.a1;
  double t0 = tmin, t1 = tmax;
  if (!clipToBox(r.origin, r.dir, {-A - margin, kClothMinY, -A - margin}, {A + margin, kClothMaxY, A + margin}, t0, t1))
    return false;
  const double step = (t1 - t0) / kClothSamples;
  double tPrev = t0, fPrev = clothGap(r, t0);
  double fPrevPrev = std::numeric_limits<double>::infinity();
  for (int i = 1; i <= kClothSamples; ++i) {
    const double ti = t0 + step * i, fi = clothGap(r, ti);
    // A near miss: a local minimum of |gap| without a crossing; its gap, with derivatives at
    // the sampled minimizer, may reach 0 inside the footprint.
    if (probe && i >= 2 && (fPrev > 0) == (fi > 0) && (fPrev > 0) == (fPrevPrev > 0) && std::fabs(fPrev) <= std::fabs(fi) &&
        std::fabs(fPrev) <= std::fabs(fPrevPrev)) {
      const T gap = clothGap(ray, T(tPrev));
      const Vec3<T> p = ray.origin + ray.dir * T(tPrev);
      if (mayCross(gap, 0.0, probe->half) && std::fabs(val(p.x)) <= A + spread(p.x, probe->half) &&
          std::fabs(val(p.z)) <= A + spread(p.z, probe->half))
        probe->flag(tPrev);
    }
    if ((fPrev > 0) != (fi > 0)) {
      if (!hit && !probe) {  // any-hit query (a plain shadow ray): both ends on the sheet suffice
        const Vec3d a = r.origin + r.dir * tPrev, b = r.origin + r.dir * ti;
        if (std::fabs(a.x) <= A && std::fabs(a.z) <= A && std::fabs(b.x) <= A && std::fabs(b.z) <= A && tPrev > tmin)
          return true;
      }
      double lo = tPrev, hi = ti, flo = fPrev;
      for (int k = 0; k < 32; ++k) {
        const double mid = 0.5 * (lo + hi), fm = clothGap(r, mid);
        if ((fm > 0) == (flo > 0)) lo = mid, flo = fm;
        else hi = mid;
      }
      const double ts = 0.5 * (lo + hi);
      // Implicit differentiation: t = ts - gap(ts) / gap_t, gap evaluated with the ray's derivatives.
      const Vec3d ps = r.origin + r.dir * ts;
      double hx, hz;
      clothSlope(ps.x, ps.z, hx, hz);
      const double gapT = r.dir.y - (hx * r.dir.x + hz * r.dir.z);
      const T t = T(ts) - clothGap(ray, T(ts)) / gapT;
      const Vec3<T> p = ray.origin + ray.dir * t;
      const bool inside = std::fabs(ps.x) <= A && std::fabs(ps.z) <= A;
      if (probe && (mayCross(p.x, -A, probe->half) || mayCross(p.x, A, probe->half) || mayCross(p.z, -A, probe->half) ||
                    mayCross(p.z, A, probe->half)))
        probe->flag(ts);
      if (inside && ts > tmin) {
        if (hit) {
          hit->t = t;
          hit->p = p;
          T hxT, hzT;
          clothSlope(p.x, p.z, hxT, hzT);
          hit->n = normalize(Vec3<T>(-hxT, T(1.0), -hzT));
          hit->tu = Vec3<T>(T(1.0), hxT, T(0.0));
          hit->u = (p.x + A) * (s.tiling / (2 * A));
          hit->v = (p.z + A) * (s.tiling / (2 * A));
        }
        return true;
      }
      fPrevPrev = std::numeric_limits<double>::infinity();  // a crossing is not a near miss
      tPrev = ti, fPrev = fi;
      continue;
    }
    fPrevPrev = fPrev;
    tPrev = ti, fPrev = fi;
  }
  return false;
}

}  // namespace detail

// Nearest hit of `ray` with `shape` in (tmin, tmax). `probe` (Dual rays) is set when the
// hit-or-miss outcome may change inside the footprint.
template <class T>
bool intersectShape(const Shape& s, const Ray<T>& ray, double tmin, double tmax, SurfaceHit<T>* hit,
                    EdgeProbe* probe = nullptr) {
  switch (s.kind) {
    case ShapeKind::Sphere: return detail::intersectSphere(s, ray, tmin, tmax, hit, probe);
    case ShapeKind::Rect: return detail::intersectRect(s, ray, tmin, tmax, hit, probe);
    case ShapeKind::Cylinder: return detail::intersectCylinder(s, ray, tmin, tmax, hit, probe);
    case ShapeKind::Cloth: return detail::intersectCloth(s, ray, tmin, tmax, hit, probe);
  }
  return false;
}

}  // namespace nbtf
