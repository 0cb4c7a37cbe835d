// Woven cloth: warp threads run down the image (along y), weft threads across (along x).
// At every crossing one of them is on top; between crossings a thread undulates (crimp)
// from over to under with a cosine. Threads have an elliptic cross-section, wander a
// little, vary in thickness (slubs) and colour, and carry the ridges of their ply twist.
#include <algorithm>
#include <cmath>

#include "synth/meso_pattern.h"

namespace nbtf::synth {
namespace {
constexpr double kPi = 3.14159265358979323846;

class WeavePattern final : public MesoPattern {
 public:
  WeavePattern(const WeaveSpec& spec, int width, int height, Rng& rng) : spec_(spec), width_(width), height_(height) {
    int repeat = spec.over + spec.under;
    if (spec.kind == WeaveKind::Plain) repeat = 2;
    numWarp_ = repeatsAcross(width, spec.warpPitch, repeat);
    numWeft_ = repeatsAcross(height, spec.weftPitch, repeat);
    warpPitch_ = static_cast<double>(width) / numWarp_;
    weftPitch_ = static_cast<double>(height) / numWeft_;
    scale_ = 0.5 * (warpPitch_ + weftPitch_);
    for (int i = 0; i < numWarp_; ++i) warpThreads_.push_back(drawThread(rng));
    for (int j = 0; j < numWeft_; ++j) weftThreads_.push_back(drawThread(rng));
    // Noise lattices: wander and slubs vary slowly along a thread, streaks are long along
    // it and narrow across it.
    warpWander_ = PeriodicNoise(rng, numWarp_, std::max(1, numWeft_ / 3));
    weftWander_ = PeriodicNoise(rng, std::max(1, numWarp_ / 3), numWeft_);
    warpSlub_ = PeriodicNoise(rng, numWarp_ * 2, std::max(1, numWeft_ / 2));
    weftSlub_ = PeriodicNoise(rng, std::max(1, numWarp_ / 2), numWeft_ * 2);
    warpStreaks_ = PeriodicFbm(rng, numWarp_ * 4, std::max(1, numWeft_ / 2), 3);
    weftStreaks_ = PeriodicFbm(rng, std::max(1, numWarp_ / 2), numWeft_ * 4, 3);
  }

  SurfacePoint eval(double x, double y) const override {
    const double u = x / width_ * numWarp_, v = y / height_ * numWeft_;
    Candidate warp = warpAt(x, y, u, v), weft = weftAt(x, y, u, v);
    SurfacePoint p;
    if (!warp.present && !weft.present) {
      // Gap between threads: the far side of the cloth, deep down.
      p.height = static_cast<float>(-scale_ * (spec_.crimp + spec_.thickness) * 1.15);
      std::copy(spec_.gapColour, spec_.gapColour + 3, p.albedo);
      p.ks = 0;
      return p;
    }
    const Candidate& top = (warp.present && (!weft.present || warp.height >= weft.height)) ? warp : weft;
    return top.point;
  }

 private:
  struct Thread {
    float brightness;  // relative colour jitter in [-1, 1]
    float thickness;   // relative thickness jitter in [-1, 1]
  };
  struct Candidate {
    bool present = false;
    float height = 0;
    SurfacePoint point;
  };

  static Thread drawThread(Rng& rng) { return {static_cast<float>(rng.symmetric()), static_cast<float>(rng.symmetric())}; }

  bool warpOver(int i, int j) const {
    i = wrapIndex(i, numWarp_), j = wrapIndex(j, numWeft_);
    switch (spec_.kind) {
      case WeaveKind::Plain: return (i + j) % 2 == 0;
      case WeaveKind::Twill: return (i + j) % (spec_.over + spec_.under) < spec_.over;
      case WeaveKind::Satin: {
        // Warp-faced satin: one binding point per repeat, offset by 2 per thread so
        // binding points never touch.
        int harness = spec_.over + spec_.under;
        return (2 * i + j) % harness != 0;
      }
    }
    return true;
  }

  // Crimp: elevation in [-1, 1] of a thread along its length, from the over/under
  // states at the crossings on either side (crossing k sits at k + 0.5).
  template <class Over>
  static double crimp(double along, Over over) {
    double c = along - 0.5;
    double k0 = std::floor(c), f = c - k0;
    double e0 = over(static_cast<int>(k0)) ? 1.0 : -1.0, e1 = over(static_cast<int>(k0) + 1) ? 1.0 : -1.0;
    return e0 + (e1 - e0) * 0.5 * (1 - std::cos(kPi * f));
  }

  // One thread at a point `offsetFraction` of a pitch beside its axis; `rel` is the point
  // relative to the thread's axis in image texels (for the ply ridges).
  Candidate yarn(const YarnLook& look, const Thread& thread, double offsetFraction, double halfWidth, double pitch,
                 double elevation, const double rel[2], const double axis[2], float streak) const {
    Candidate c;
    double s = offsetFraction / halfWidth;
    if (std::fabs(s) >= 1) return c;
    double profile = spec_.flatness == 2 ? std::sqrt(1 - s * s)
                                         : std::pow(1 - std::pow(std::fabs(s), spec_.flatness), 1 / spec_.flatness);
    double thickness = spec_.thickness * (1 + 0.5 * spec_.slub * thread.thickness);
    PlyResult ply = plyRidges(rel, axis, look.twistDeg, look.plyPeriod * pitch, axis[0] != 0 ? width_ : height_);
    double h = scale_ * (spec_.crimp * elevation + thickness * profile * (1 + look.plyDepth * ply.ridge));
    c.present = true;
    c.height = static_cast<float>(h);
    SurfacePoint& p = c.point;
    p.height = c.height;
    float shade = (1 + look.colourJitter * thread.brightness) * (1 + look.streaks * streak) *
                  static_cast<float>(1 - 0.15 * s * s) * static_cast<float>(1 + 0.08 * ply.ridge);
    for (int k = 0; k < 3; ++k) p.albedo[k] = std::clamp(look.colour[k] * shade, 0.0f, 0.95f);
    p.tangent[0] = ply.tangent[0], p.tangent[1] = ply.tangent[1];
    p.ks = look.ks, p.alphaT = look.alphaT, p.alphaB = look.alphaB;
    p.sheen = look.sheen, p.sheenRoughness = look.sheenRoughness;
    return c;
  }

  Candidate warpAt(double x, double y, double u, double v) const {
    double uw = u + spec_.wander * tileNoise(warpWander_, x, y, width_, height_);
    int i = static_cast<int>(std::floor(uw));
    const Thread& t = warpThreads_[wrapIndex(i, numWarp_)];
    double halfWidth = spec_.halfWidth * (1 + spec_.slub * (0.5 * t.thickness + tileNoise(warpSlub_, x, y, width_, height_)));
    double elevation = crimp(v, [&](int j) { return warpOver(i, j); });
    static const double axis[2] = {0, 1};
    const double rel[2] = {(uw - i - 0.5) * warpPitch_, y};
    return yarn(spec_.warp, t, uw - i - 0.5, halfWidth, warpPitch_, elevation, rel, axis,
                tileNoise(warpStreaks_, x, y, width_, height_));
  }

  Candidate weftAt(double x, double y, double u, double v) const {
    double vw = v + spec_.wander * tileNoise(weftWander_, x, y, width_, height_);
    int j = static_cast<int>(std::floor(vw));
    const Thread& t = weftThreads_[wrapIndex(j, numWeft_)];
    double halfWidth = spec_.halfWidth * (1 + spec_.slub * (0.5 * t.thickness + tileNoise(weftSlub_, x, y, width_, height_)));
    double elevation = crimp(u, [&](int i) { return !warpOver(i, j); });
    static const double axis[2] = {1, 0};
    const double rel[2] = {x, (vw - j - 0.5) * weftPitch_};
    return yarn(spec_.weft, t, vw - j - 0.5, halfWidth, weftPitch_, elevation, rel, axis,
                tileNoise(weftStreaks_, x, y, width_, height_));
  }

  WeaveSpec spec_;
  int width_, height_;
  int numWarp_, numWeft_;
  double warpPitch_, weftPitch_, scale_;
  std::vector<Thread> warpThreads_, weftThreads_;
  PeriodicNoise warpWander_, weftWander_, warpSlub_, weftSlub_;
  PeriodicFbm warpStreaks_, weftStreaks_;
};

}  // namespace

std::unique_ptr<MesoPattern> makeWeave(const WeaveSpec& spec, int width, int height, Rng& rng) {
  return std::make_unique<WeavePattern>(spec, width, height, rng);
}

}  // namespace nbtf::synth
