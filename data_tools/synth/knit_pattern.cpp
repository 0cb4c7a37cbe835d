// Stockinette knit: columns of V-shaped stitches. Each stitch has two plump legs
// running from the top corners of its cell to the bottom centre; a leg is highest in
// the middle and dips at both ends, where it passes behind the neighbouring stitches.
// Between the legs the knit is open and deep, so the material shadows and masks itself
// strongly. Wool fuzz roughens the surface; heathered fibres mix two colours.
#include <algorithm>
#include <cmath>

#include "synth/meso_pattern.h"

namespace nbtf::synth {
namespace {
constexpr double kPi = 3.14159265358979323846;

struct KnitLook {
  double columnPitch = 18, rowPitch = 13;  // target texels per stitch across / down
  double yarnRadius = 0.19;                // yarn half-width, fraction of the column pitch
  double loft = 0.9;                       // yarn half-height / half-width
  double dip = 0.65;                       // how far a leg's ends sink, in yarn radii
  double fuzz = 0.06;                      // fuzz height, in yarn radii
  float primary[3] = {0.30f, 0.045f, 0.035f};
  float fleck[3] = {0.55f, 0.45f, 0.33f};
  double twistDeg = 35, plySpacing = 0.7;  // ply ridges, spacing in yarn radii
};

class KnitPattern final : public MesoPattern {
 public:
  KnitPattern(int width, int height, Rng& rng) : width_(width), height_(height) {
    columns_ = repeatsAcross(width, look_.columnPitch);
    rows_ = repeatsAcross(height, look_.rowPitch);
    cellW_ = static_cast<double>(width) / columns_;
    cellH_ = static_cast<double>(height) / rows_;
    radius_ = look_.yarnRadius * cellW_;
    for (int i = 0; i < columns_ * rows_; ++i) {
      Stitch s;
      for (double& j : s.jitter) j = rng.symmetric();
      s.size = static_cast<float>(rng.symmetric());
      s.brightness = static_cast<float>(rng.symmetric());
      stitches_.push_back(s);
    }
    auto cells = [&](double texels, int size) { return std::max(1, static_cast<int>(std::lround(size / texels))); };
    fuzz_ = PeriodicFbm(rng, cells(2.5, width), cells(2.5, height), 2, 0.6);
    flecks_ = PeriodicNoise(rng, cells(1.2, width), cells(2.0, height));
    heather_ = PeriodicFbm(rng, cells(6, width), cells(6, height), 3);
  }

  SurfacePoint eval(double x, double y) const override {
    int c = static_cast<int>(std::floor(x / cellW_)), r = static_cast<int>(std::floor(y / cellH_));
    Leg best;
    for (int dr = -1; dr <= 1; ++dr)
      for (int dc = -1; dc <= 1; ++dc)
        for (int side = 0; side < 2; ++side) {
          Leg leg = legAt(x, y, c + dc, r + dr, side);
          if (leg.present && leg.height > best.height) best = leg;
        }
    SurfacePoint p;
    float fuzz = tileNoise(fuzz_, x, y, width_, height_);
    float heather = tileNoise(heather_, x, y, width_, height_);
    float fleckMix = smoothstep(0.6f, 0.85f, tileNoise(flecks_, x, y, width_, height_));
    float colour[3];
    for (int k = 0; k < 3; ++k) colour[k] = look_.primary[k] + (look_.fleck[k] - look_.primary[k]) * fleckMix;
    p.ks = 0.025f, p.alphaT = 0.25f, p.alphaB = 0.6f;
    p.sheen = 0.35f, p.sheenRoughness = 0.5f;
    if (!best.present) {
      // Deep inside the knit: loose fibres of the stitches behind, barely lit.
      p.height = static_cast<float>(-radius_ * (1.4 - look_.fuzz * fuzz));
      for (int k = 0; k < 3; ++k) p.albedo[k] = 0.3f * colour[k];
      return p;
    }
    p.height = static_cast<float>(best.height + look_.fuzz * radius_ * fuzz);
    float shade = (1 + 0.06f * best.brightness) * (0.85f + 0.3f * heather) * (1 - 0.2f * best.across * best.across) *
                  (1 + 0.1f * best.ridge);
    for (int k = 0; k < 3; ++k) p.albedo[k] = std::clamp(colour[k] * shade, 0.0f, 0.95f);
    p.tangent[0] = best.tangent[0], p.tangent[1] = best.tangent[1];
    return p;
  }

 private:
  struct Stitch {
    double jitter[4];        // endpoint offsets, in [-1, 1]
    float size, brightness;  // relative jitter in [-1, 1]
  };
  struct Leg {
    bool present = false;
    double height = -1e30;
    float across = 0;  // -1..1 across the yarn
    float ridge = 0;
    float tangent[2] = {0, 1};
    float brightness = 0;
  };

  // Leg `side` (0 = left, 1 = right) of the stitch in column c, row r, at point (x, y).
  Leg legAt(double x, double y, int c, int r, int side) const {
    const Stitch& s = stitches_[wrapIndex(r, rows_) * columns_ + wrapIndex(c, columns_)];
    double ox = c * cellW_, oy = r * cellH_;
    double ax = ox + ((side == 0 ? 0.16 : 0.84) + 0.03 * s.jitter[side]) * cellW_;
    double ay = oy + (-0.25 + 0.04 * s.jitter[2]) * cellH_;
    double bx = ox + ((side == 0 ? 0.44 : 0.56) + 0.02 * s.jitter[3]) * cellW_, by = oy + 1.0 * cellH_;
    double sx = bx - ax, sy = by - ay, len2 = sx * sx + sy * sy;
    double t = std::clamp(((x - ax) * sx + (y - ay) * sy) / len2, 0.0, 1.0);
    double qx = ax + t * sx, qy = ay + t * sy;
    double dx = x - qx, dy = y - qy;
    double radius = radius_ * (1 + 0.08 * s.size);
    double d2 = dx * dx + dy * dy;
    Leg leg;
    if (d2 >= radius * radius) return leg;
    double len = std::sqrt(len2);
    double axis[2] = {sx / len, sy / len};
    double across = (axis[0] * dy - axis[1] * dx) / radius;  // signed, -1..1
    double profile = std::sqrt(1 - d2 / (radius * radius));
    double lift = std::pow(std::sin(kPi * t), 0.6) - 1;  // 0 mid-leg, -1 at the ends
    double rel[2] = {x - ax, y - ay};
    PlyResult ply = plyRidges(rel, axis, side == 0 ? look_.twistDeg : -look_.twistDeg, look_.plySpacing * radius);
    leg.present = true;
    leg.height = radius * (look_.loft * profile * (1 + 0.08 * ply.ridge) + look_.dip * lift);
    leg.across = static_cast<float>(across);
    leg.ridge = ply.ridge;
    leg.tangent[0] = ply.tangent[0], leg.tangent[1] = ply.tangent[1];
    leg.brightness = s.brightness;
    return leg;
  }

  KnitLook look_;
  int width_, height_;
  int columns_, rows_;
  double cellW_, cellH_, radius_;
  std::vector<Stitch> stitches_;
  PeriodicFbm fuzz_, heather_;
  PeriodicNoise flecks_;
};

}  // namespace

std::unique_ptr<MesoPattern> makeKnit(int width, int height, Rng& rng) {
  return std::make_unique<KnitPattern>(width, height, rng);
}

}  // namespace nbtf::synth
