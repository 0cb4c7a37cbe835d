#include "synth/surface.h"

#include <algorithm>
#include <cmath>

#include "util/parallel.h"

namespace nbtf::synth {
namespace {
constexpr double kPi = 3.14159265358979323846;

void normalize3(float* v) {
  float n = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  v[0] /= n, v[1] /= n, v[2] /= n;
}
}  // namespace

// ---- Sampling the pattern ------------------------------------------------------------

Surface::Surface(const MesoPattern& pattern, int width, int height, int supersampling)
    : width_(width), height_(height), ss_(supersampling), fineW_(width * supersampling), fineH_(height * supersampling) {
  std::size_t n = static_cast<std::size_t>(fineW_) * fineH_;
  std::vector<SurfacePoint> raw(n);
  heights_.resize(n);
  parallelFor(fineH_, [&](std::size_t r0, std::size_t r1) {
    for (std::size_t r = r0; r < r1; ++r)
      for (int c = 0; c < fineW_; ++c) {
        std::size_t i = r * fineW_ + c;
        raw[i] = pattern.eval((c + 0.5) / ss_, (r + 0.5) / ss_);
        heights_[i] = raw[i].height;
      }
  });
  auto [lo, hi] = std::minmax_element(heights_.begin(), heights_.end());
  minHeight_ = *lo, maxHeight_ = *hi;
  double sum = 0, albedo[3] = {0, 0, 0};
  for (std::size_t i = 0; i < n; ++i) {
    sum += heights_[i];
    for (int k = 0; k < 3; ++k) albedo[k] += raw[i].albedo[k];
  }
  referenceHeight_ = static_cast<float>(sum / n);
  for (int k = 0; k < 3; ++k) meanAlbedo_[k] = static_cast<float>(albedo[k] / n);

  // Normals by central differences (texel units), then the fibre frame and the BRDF
  // constants. Image rows run down, the frame's y runs up.
  points_.resize(n);
  parallelFor(fineH_, [&](std::size_t r0, std::size_t r1) {
    for (std::size_t r = r0; r < r1; ++r)
      for (int c = 0; c < fineW_; ++c) {
        std::size_t i = r * fineW_ + c;
        const SurfacePoint& s = raw[i];
        ShadingPoint& p = points_[i];
        int cl = wrapIndex(c - 1, fineW_), cr = wrapIndex(c + 1, fineW_);
        int ru = wrapIndex(static_cast<int>(r) - 1, fineH_), rd = wrapIndex(static_cast<int>(r) + 1, fineH_);
        float dhdx = (heights_[r * fineW_ + cr] - heights_[r * fineW_ + cl]) * 0.5f * ss_;
        float dhdRow = (heights_[static_cast<std::size_t>(rd) * fineW_ + c] -
                        heights_[static_cast<std::size_t>(ru) * fineW_ + c]) * 0.5f * ss_;
        p.normal[0] = -dhdx, p.normal[1] = dhdRow, p.normal[2] = 1;
        normalize3(p.normal);
        float t[3] = {s.tangent[0], -s.tangent[1], 0};
        float tn = t[0] * p.normal[0] + t[1] * p.normal[1];
        for (int k = 0; k < 3; ++k) t[k] -= tn * p.normal[k];
        normalize3(t);
        std::copy(t, t + 3, p.tangent);
        p.bitangent[0] = p.normal[1] * t[2] - p.normal[2] * t[1];
        p.bitangent[1] = p.normal[2] * t[0] - p.normal[0] * t[2];
        p.bitangent[2] = p.normal[0] * t[1] - p.normal[1] * t[0];
        std::copy(s.albedo, s.albedo + 3, p.albedo);
        p.wardWeight = s.ks / (4 * s.alphaT * s.alphaB);
        p.invAlphaT2 = 1 / (s.alphaT * s.alphaT);
        p.invAlphaB2 = 1 / (s.alphaB * s.alphaB);
        p.sheenWeight = s.sheen * (2 + 1 / s.sheenRoughness) / 2;
        p.sheenHalfExponent = 0.5f / s.sheenRoughness;
      }
  });
  parallelFor(n, [&](std::size_t i0, std::size_t i1) {
    for (std::size_t i = i0; i < i1; ++i) points_[i].occlusion = 1 - skyVisibility(i);
  }, 256);
}

// ---- Ray marching ----------------------------------------------------------------------

float Surface::heightAt(double column, double row) const {
  double fc = std::floor(column), fr = std::floor(row);
  int c0 = wrapIndex(static_cast<int>(fc), fineW_), r0 = wrapIndex(static_cast<int>(fr), fineH_);
  int c1 = c0 + 1 == fineW_ ? 0 : c0 + 1, r1 = r0 + 1 == fineH_ ? 0 : r0 + 1;
  float tx = static_cast<float>(column - fc), ty = static_cast<float>(row - fr);
  const float* a = heights_.data() + static_cast<std::size_t>(r0) * fineW_;
  const float* b = heights_.data() + static_cast<std::size_t>(r1) * fineW_;
  float top = a[c0] + (a[c1] - a[c0]) * tx, bottom = b[c0] + (b[c1] - b[c0]) * tx;
  return top + (bottom - top) * ty;
}

float Surface::visibility(std::size_t sample, const double dir[3], float hardness) const {
  double horizontal = std::hypot(dir[0], dir[1]);
  if (horizontal < 1e-9) return 1;  // straight up: nothing on a height field is above
  double stepC = dir[0] / horizontal, stepR = -dir[1] / horizontal;
  double rise = dir[2] / horizontal / ss_;  // texels of height per fine step
  double c0 = static_cast<double>(sample % fineW_), r0 = static_cast<double>(sample / fineW_);
  double h0 = heights_[sample] + 0.01;
  double res = 1;
  // The ray leaves the height field once above its maximum; a direction at the horizon
  // never does, so the march is bounded by a few tile widths.
  int maxSteps = 4 * std::max(fineW_, fineH_);
  for (int t = 1; t <= maxSteps; ++t) {
    double z = h0 + rise * t;
    if (z > maxHeight_) break;
    double gap = z - heightAt(c0 + stepC * t, r0 + stepR * t);
    res = std::min(res, hardness * gap * ss_ / t);  // gap / distance ~ the angle it clears by
    if (res <= 0) return 0;
  }
  return static_cast<float>(res * res * (3 - 2 * res));
}

std::size_t Surface::parallaxHit(std::size_t sample, const double view[3]) const {
  double horizontal = std::hypot(view[0], view[1]);
  if (horizontal < 1e-9) return sample;
  // March from the viewer's side down along -view, one fine step at a time.
  double stepC = -view[0] / horizontal, stepR = view[1] / horizontal;
  double rise = view[2] / horizontal / ss_;
  double c0 = static_cast<double>(sample % fineW_), r0 = static_cast<double>(sample / fineW_);
  auto z = [&](double t) { return referenceHeight_ - rise * t; };
  auto gapAt = [&](double t) { return z(t) - heightAt(c0 + stepC * t, r0 + stepR * t); };
  double t = -(maxHeight_ - referenceHeight_) / rise - 1e-6;
  double prevGap = gapAt(t);
  double hit = t;
  int maxSteps = 8 * std::max(fineW_, fineH_) + static_cast<int>(std::ceil((maxHeight_ - minHeight_) / rise)) + 2;
  for (int step = 0; step < maxSteps; ++step) {
    double next = t + 1;
    double gap = gapAt(next);
    if (gap <= 0) {
      hit = t + prevGap / (prevGap - gap);  // secant between the last two steps
      break;
    }
    t = next, prevGap = gap, hit = t;
    if (z(t) < minHeight_) break;
  }
  int c = wrapIndex(static_cast<int>(std::lround(c0 + stepC * hit)), fineW_);
  int r = wrapIndex(static_cast<int>(std::lround(r0 + stepR * hit)), fineH_);
  return static_cast<std::size_t>(r) * fineW_ + c;
}

// Cosine-weighted sky visibility from the horizon angle in 8 azimuths: an azimuth
// slice whose horizon rises to elevation e keeps cos^2(e) of its cosine weight.
float Surface::skyVisibility(std::size_t sample) const {
  const int azimuths = 8;
  double c0 = static_cast<double>(sample % fineW_), r0 = static_cast<double>(sample / fineW_);
  double h0 = heights_[sample];
  int maxSteps = std::min(24 * ss_, std::max(fineW_, fineH_));
  double sum = 0;
  for (int a = 0; a < azimuths; ++a) {
    double angle = 2 * kPi * a / azimuths;
    double dc = std::cos(angle), dr = std::sin(angle);
    double maxTan = 0;
    for (int t = 1; t <= maxSteps; ++t) {
      double distance = static_cast<double>(t) / ss_;
      if ((maxHeight_ - h0) / distance <= maxTan) break;  // nothing further can rise above it
      maxTan = std::max(maxTan, (heightAt(c0 + dc * t, r0 + dr * t) - h0) / distance);
    }
    sum += 1 / (1 + maxTan * maxTan);
  }
  return static_cast<float>(sum / azimuths);
}

}  // namespace nbtf::synth
