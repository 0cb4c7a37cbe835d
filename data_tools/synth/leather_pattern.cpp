// Lacquered leather: a pebbled grain of rounded cells (cellular noise) separated by
// creases, fine pores, and low-frequency mottling, under a glossy clear coat. The coat
// is a dielectric (the preset turns on Fresnel): sharp on the pebbles, duller in the
// creases where the lacquer is thin and the surface rough.
#include <algorithm>
#include <cmath>

#include "synth/meso_pattern.h"

namespace nbtf::synth {
namespace {

class LeatherPattern final : public MesoPattern {
 public:
  LeatherPattern(int width, int height, Rng& rng) : width_(width), height_(height) {
    int cx = repeatsAcross(width, 9.0), cy = repeatsAcross(height, 9.0);
    cellSize_ = 0.5 * (static_cast<double>(width) / cx + static_cast<double>(height) / cy);
    cells_ = PeriodicCells(rng, cx, cy, 0.85);
    for (int i = 0; i < cx * cy; ++i) cellJitter_.push_back(static_cast<float>(rng.symmetric()));
    auto cells = [&](double texels, int size) { return std::max(1, static_cast<int>(std::lround(size / texels))); };
    pores_ = PeriodicCells(rng, cells(3.2, width), cells(3.2, height), 0.9);
    for (int i = 0; i < pores_.cellsX() * pores_.cellsY(); ++i) poreSize_.push_back(static_cast<float>(rng.uniform()));
    mottle_ = PeriodicFbm(rng, cells(24, width), cells(24, height), 3);
    warpU_ = PeriodicFbm(rng, cells(5, width), cells(5, height), 2);
    warpV_ = PeriodicFbm(rng, cells(5, width), cells(5, height), 2);
  }

  SurfacePoint eval(double x, double y) const override {
    // Warp the cell lookup so creases wiggle instead of running straight.
    double wu = 0.22 * tileNoise(warpU_, x, y, width_, height_), wv = 0.22 * tileNoise(warpV_, x, y, width_, height_);
    float f1, f2;
    int cell;
    cells_.eval(x / width_ * cells_.cellsX() + wu, y / height_ * cells_.cellsY() + wv, f1, f2, cell);
    float edge = f2 - f1;                       // 0 on a crease
    float plateau = smoothstep(0.0f, 0.32f, edge);
    float dome = 1 - 0.5f * f1 * f1;            // pebbles are rounded
    // Pores: small round dimples around the feature points of a finer cell grid, in
    // about half of its cells, of varying size.
    float pf1, pf2;
    int poreCell;
    pores_.eval(x / width_ * pores_.cellsX(), y / height_ * pores_.cellsY(), pf1, pf2, poreCell);
    float poreRadius = 0.28f * std::max(0.0f, poreSize_[poreCell] - 0.45f) / 0.55f;
    float pore = poreRadius > 0 ? 1 - smoothstep(0.5f * poreRadius, poreRadius, pf1) : 0.0f;
    float mottle = tileNoise(mottle_, x, y, width_, height_);
    double depth = 0.11 * cellSize_;
    SurfacePoint p;
    p.height = static_cast<float>(depth * (plateau * (0.75 + 0.25 * dome) - 1 - 0.25 * pore));
    static const float colour[3] = {0.17f, 0.040f, 0.028f};
    float shade = (0.55f + 0.45f * plateau) * (1 + 0.15f * mottle) * (1 + 0.05f * cellJitter_[cell]) * (1 - 0.25f * pore);
    for (int k = 0; k < 3; ++k) p.albedo[k] = std::clamp(colour[k] * shade, 0.0f, 0.95f);
    p.ks = 0.02f * (0.35f + 0.65f * plateau) * (1 - 0.5f * pore);
    p.alphaT = p.alphaB = 0.22f + (0.09f - 0.22f) * plateau;
    p.tangent[0] = 1, p.tangent[1] = 0;
    return p;
  }

 private:
  int width_, height_;
  double cellSize_;
  PeriodicCells cells_;
  std::vector<float> cellJitter_;
  PeriodicCells pores_;
  std::vector<float> poreSize_;
  PeriodicFbm mottle_, warpU_, warpV_;
};

}  // namespace

std::unique_ptr<MesoPattern> makeLeather(int width, int height, Rng& rng) {
  return std::make_unique<LeatherPattern>(width, height, rng);
}

}  // namespace nbtf::synth
