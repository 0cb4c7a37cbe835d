// Corduroy: parallel wales of cut pile running down the image, separated by narrow
// grooves where the plain-woven backing shows. The pile is velvety: a strong sheen
// lobe, a weak anisotropic lobe along the wale (the brushed nap), and dense fine noise.
#include <algorithm>
#include <cmath>

#include "synth/meso_pattern.h"

namespace nbtf::synth {
namespace {
constexpr double kPi = 3.14159265358979323846;

class CorduroyPattern final : public MesoPattern {
 public:
  CorduroyPattern(int width, int height, Rng& rng) : width_(width), height_(height) {
    wales_ = repeatsAcross(width, 11.0);
    pitch_ = static_cast<double>(width) / wales_;
    for (int i = 0; i < wales_; ++i) waleJitter_.push_back(static_cast<float>(rng.symmetric()));
    auto cells = [&](double texels, int size) { return std::max(1, static_cast<int>(std::lround(size / texels))); };
    wander_ = PeriodicNoise(rng, wales_, std::max(1, wales_ / 4));
    pile_ = PeriodicFbm(rng, cells(1.5, width), cells(1.5, height), 2, 0.6);
    brush_ = PeriodicFbm(rng, wales_ * 3, std::max(1, cells(25, height)), 3);
    backingX_ = std::max(1, static_cast<int>(std::lround(width / (pitch_ / 4))));
    backingY_ = std::max(1, static_cast<int>(std::lround(height / (pitch_ / 4))));
  }

  SurfacePoint eval(double x, double y) const override {
    double u = x / width_ * wales_ + 0.04 * tileNoise(wander_, x, y, width_, height_);
    int i = static_cast<int>(std::floor(u));
    double d = u - i - 0.5;  // -0.5..0.5 across the wale
    float jitter = waleJitter_[wrapIndex(i, wales_)];
    double halfWidth = 0.41 * (1 + 0.04 * jitter);
    float pile = tileNoise(pile_, x, y, width_, height_);
    float brush = tileNoise(brush_, x, y, width_, height_);
    SurfacePoint p;
    p.tangent[0] = 0, p.tangent[1] = 1;
    double top = 0.36 * pitch_;
    if (std::fabs(d) < halfWidth) {
      double s = std::fabs(d) / halfWidth;
      p.height = static_cast<float>(top * std::pow(1 - s * s, 0.35) + 0.03 * pitch_ * pile);
      static const float colour[3] = {0.30f, 0.17f, 0.075f};
      float shade = (1 + 0.05f * jitter) * (0.85f + 0.3f * pile) * (1 + 0.12f * brush) * static_cast<float>(1 - 0.25 * s * s * s * s);
      for (int k = 0; k < 3; ++k) p.albedo[k] = std::clamp(colour[k] * shade, 0.0f, 0.95f);
      p.ks = 0.02f, p.alphaT = 0.3f, p.alphaB = 0.6f;
      p.sheen = 0.8f, p.sheenRoughness = 0.3f;
    } else {
      // The backing: a tight plain weave, only bumps at this scale.
      double bumps = std::cos(2 * kPi * x / width_ * backingX_) * std::cos(2 * kPi * y / height_ * backingY_);
      p.height = static_cast<float>(0.04 * top + 0.03 * pitch_ * bumps);
      static const float backing[3] = {0.16f, 0.11f, 0.06f};
      for (int k = 0; k < 3; ++k) p.albedo[k] = backing[k] * static_cast<float>(0.9 + 0.1 * bumps);
      p.ks = 0.01f, p.alphaT = 0.35f, p.alphaB = 0.35f;
      p.sheen = 0.1f, p.sheenRoughness = 0.5f;
    }
    return p;
  }

 private:
  int width_, height_;
  int wales_;
  double pitch_;
  int backingX_, backingY_;
  std::vector<float> waleJitter_;
  PeriodicNoise wander_;
  PeriodicFbm pile_, brush_;
};

}  // namespace

std::unique_ptr<MesoPattern> makeCorduroy(int width, int height, Rng& rng) {
  return std::make_unique<CorduroyPattern>(width, height, rng);
}

}  // namespace nbtf::synth
