#include "gltf/gltf_fit.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <numeric>
#include <vector>

#include "util/error.h"
#include "util/parallel.h"
#include "util/progress.h"
#include "util/random.h"

namespace nbtf::gltf {
namespace {

constexpr double kPi = 3.14159265358979323846;
// base colour r, g, b; metallic; roughness; normal slopes x, y; sheen colour r, g, b; sheen
// roughness; the dielectric's F0 (KHR_materials_specular; 0.04 without it)
constexpr int kParams = 12;
constexpr double kMinSheenRoughness = 0.1;
using Params = std::array<double, kParams>;

// One sample's value is linear in the base colour, the metallic factor and the sheen colour:
// value_c = scale (base_c) + sheen_c sh, base_c = (1 - m) (a0 b_c + b0) + m (a1 b_c + b1),
// scale = 1 - 0.157 max(sheen colour); each lobe already x exposure x cos(theta_l).
struct Lobes {
  double a0 = 0, b0 = 0, a1 = 0, b1 = 0, sh = 0;
  double kd = 0, ks = 0, t = 0;  // exposure cos / pi, exposure cos D V, 1 - Schlick: d(a0, b0) / dF0
  double base(double b, double m) const { return (1 - m) * (a0 * b + b0) + m * (a1 * b + b1); }
};

double sheenMax(const Params& x) { return std::max({x[7], x[8], x[9]}); }
double valueOf(const Lobes& L, const Params& x, int c) {
  return (1 - kSheenAlbedoScale * sheenMax(x)) * L.base(x[c], x[3]) + x[7 + c] * L.sh;
}

Vec3 normalOf(double px, double py) {
  const double len = std::sqrt(px * px + py * py + 1);
  return {px / len, py / len, 1 / len};
}

Lobes lobes(double roughness, double sheenRoughness, bool sheen, double f0, const Vec3& n, const Vec3& l,
            const Vec3& v, double exposure) {
  const double nl = n[0] * l[0] + n[1] * l[1] + n[2] * l[2];
  const double nv = n[0] * v[0] + n[1] * v[1] + n[2] * v[2];
  if (nl <= 0 || nv <= 0) return {};
  Vec3 h{l[0] + v[0], l[1] + v[1], l[2] + v[2]};
  const double hl = std::sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
  if (!(hl > 0)) return {};
  const double nh = (n[0] * h[0] + n[1] * h[1] + n[2] * h[2]) / hl;
  const double vh = std::abs(v[0] * h[0] + v[1] * h[1] + v[2] * h[2]) / hl;
  const double alpha = std::max(roughness * roughness, kMinAlpha);
  const double s = ggxDistribution(alpha, nh) * smithVisibility(alpha, nl, nv);
  const double t = 1 - vh, schlick = t * t * t * t * t;
  const double fd = f0 + (1 - f0) * schlick;
  const double k = exposure * nl;
  const double sh = sheen ? k * charlieDistribution(sheenRoughness, nh) * sheenVisibility(nl, nv) : 0;
  return {k * (1 - fd) / kPi, k * fd * s, k * s * (1 - schlick), k * s * schlick, sh, k / kPi, k * s, 1 - schlick};
}

struct Texel {
  const Vec3 *lights, *views;
  const float* values;
  std::size_t count;
  double exposure;
  double maxSlope;
  double minRoughness;
  bool sheen;
  bool specular;

  // The lobes at x, or with parameter `moved` moved by `h`.
  Lobes at(const Params& x, std::size_t i, int moved = -1, double h = 0) const {
    Params y = x;
    if (moved >= 0) y[moved] += h;
    return lobes(y[4], y[10], sheen, y[11], normalOf(y[5], y[6]), lights[i], views[i], exposure);
  }

  double cost(const Params& x) const {
    double sum = 0;
    for (std::size_t i = 0; i < count; ++i) {
      const Lobes L = at(x, i);
      for (int c = 0; c < 3; ++c) {
        const double d = valueOf(L, x, c) - values[3 * i + c];
        sum += d * d;
      }
    }
    return sum;
  }

  void clamp(Params& x) const {
    for (int c = 0; c < 4; ++c) x[c] = std::clamp(x[c], 0.0, 1.0);
    x[4] = std::clamp(x[4], minRoughness, 1.0);
    const double slope = std::hypot(x[5], x[6]);
    if (slope > maxSlope) x[5] *= maxSlope / slope, x[6] *= maxSlope / slope;
    for (int c = 7; c < 10; ++c) x[c] = sheen ? std::clamp(x[c], 0.0, 1.0) : 0;
    x[10] = sheen ? std::clamp(x[10], kMinSheenRoughness, 1.0) : 0;
    x[11] = specular ? std::clamp(x[11], 0.0, 1.0) : kDielectricF0;
  }

  // Base colour by least squares for the other parameters (the value is linear in it).
  void solveBaseColor(Params& x) const {
    std::array<double, 3> num{}, den{};
    const double scale = 1 - kSheenAlbedoScale * sheenMax(x);
    for (std::size_t i = 0; i < count; ++i) {
      const Lobes L = at(x, i);
      const double a = scale * ((1 - x[3]) * L.a0 + x[3] * L.a1), b = scale * ((1 - x[3]) * L.b0 + x[3] * L.b1);
      for (int c = 0; c < 3; ++c) num[c] += a * (values[3 * i + c] - b - x[7 + c] * L.sh), den[c] += a * a;
    }
    for (int c = 0; c < 3; ++c) x[c] = den[c] > 0 ? num[c] / den[c] : 0.5;
    clamp(x);
  }

  // Normal equations J^T J and J^T r at x: base colour, metallic, sheen colour and F0
  // analytically, the roughnesses and the normal's slopes by forward differences.
  double normalEquations(const Params& x, double jtj[kParams][kParams], double jtr[kParams]) const {
    constexpr double h = 1e-4;
    const double hr = x[4] + h <= 1 ? h : -h, hs = x[10] + h <= 1 ? h : -h;
    for (int a = 0; a < kParams; ++a) {
      jtr[a] = 0;
      for (int b = 0; b < kParams; ++b) jtj[a][b] = 0;
    }
    const double scale = 1 - kSheenAlbedoScale * sheenMax(x);
    const int brightest = static_cast<int>(std::max_element(x.begin() + 7, x.begin() + 10) - (x.begin() + 7));
    double sum = 0;
    for (std::size_t i = 0; i < count; ++i) {
      const Lobes L = at(x, i), Lr = at(x, i, 4, hr), Lx = at(x, i, 5, h), Ly = at(x, i, 6, h);
      const Lobes Ls = sheen ? at(x, i, 10, hs) : L;
      const double m = x[3];
      for (int c = 0; c < 3; ++c) {
        const double f = valueOf(L, x, c);
        const double r = f - values[3 * i + c];
        double g[kParams] = {};
        g[c] = scale * ((1 - m) * L.a0 + m * L.a1);
        g[3] = scale * ((L.a1 - L.a0) * x[c] + (L.b1 - L.b0));
        g[4] = (valueOf(Lr, x, c) - f) / hr;
        g[5] = (valueOf(Lx, x, c) - f) / h;
        g[6] = (valueOf(Ly, x, c) - f) / h;
        if (sheen) {
          g[7 + c] = L.sh;
          g[7 + brightest] -= kSheenAlbedoScale * L.base(x[c], m);
          g[10] = (valueOf(Ls, x, c) - f) / hs;
        }
        if (specular) g[11] = scale * (1 - m) * L.t * (L.ks - L.kd * x[c]);
        for (int a = 0; a < kParams; ++a) {
          if (g[a] == 0) continue;
          jtr[a] += g[a] * r;
          for (int b = 0; b < kParams; ++b) jtj[a][b] += g[a] * g[b];
        }
        sum += r * r;
      }
    }
    return sum;
  }
};

// Solves (A + lambda diag(A)) d = -g by Cholesky; false when not positive definite.
bool dampedStep(const double A[kParams][kParams], const double g[kParams], double lambda, double d[kParams]) {
  double L[kParams][kParams] = {};
  for (int i = 0; i < kParams; ++i) {
    for (int j = 0; j <= i; ++j) {
      double s = A[i][j];
      if (i == j) s += lambda * A[i][i] + 1e-12;
      for (int k = 0; k < j; ++k) s -= L[i][k] * L[j][k];
      if (i == j) {
        if (!(s > 0)) return false;
        L[i][i] = std::sqrt(s);
      } else {
        L[i][j] = s / L[j][j];
      }
    }
  }
  double y[kParams];
  for (int i = 0; i < kParams; ++i) {
    double s = -g[i];
    for (int k = 0; k < i; ++k) s -= L[i][k] * y[k];
    y[i] = s / L[i][i];
  }
  for (int i = kParams - 1; i >= 0; --i) {
    double s = y[i];
    for (int k = i + 1; k < kParams; ++k) s -= L[k][i] * d[k];
    d[i] = s / L[i][i];
  }
  return true;
}

// `steps` Levenberg-Marquardt steps from x (kept inside the bounds); returns the cost.
double levenbergMarquardt(const Texel& t, Params& x, int steps) {
  double lambda = 1e-2;
  double jtj[kParams][kParams], jtr[kParams];
  double cost = t.normalEquations(x, jtj, jtr);
  for (int s = 0; s < steps; ++s) {
    bool accepted = false;
    for (int attempt = 0; attempt < 6 && !accepted; ++attempt) {
      double d[kParams];
      if (dampedStep(jtj, jtr, lambda, d)) {
        Params trial = x;
        for (int a = 0; a < kParams; ++a) trial[a] += d[a];
        t.clamp(trial);
        const double c = t.cost(trial);
        if (c < cost) {
          x = trial;
          accepted = true;
          lambda = std::max(lambda * 0.3, 1e-7);
          break;
        }
      }
      lambda *= 8;
    }
    if (!accepted) break;  // no step lowers the cost: converged (or stuck at a bound)
    const double previous = cost;
    cost = t.normalEquations(x, jtj, jtr);
    if (previous - cost <= 1e-9 * previous) break;  // converged to double precision's taste

  }
  return cost;
}

}  // namespace

void checkFitOptions(const FitOptions& o) {
  if (o.samples < 8) throw Error("--samples must be at least 8, got " + std::to_string(o.samples));
  if (o.iterations < 0 || o.iterations > 1000)
    throw Error("--iterations must be in 0..1000, got " + std::to_string(o.iterations));
  if (!(o.maxTiltDeg >= 0 && o.maxTiltDeg <= 80)) throw Error("--max-tilt must be in 0..80 degrees");
  if (!(o.minRoughness >= 0.01 && o.minRoughness <= 1)) throw Error("--min-roughness must be in 0.01..1");
}

namespace {
// The largest value (any channel) the parameters predict at any measured (light, view) pair.
double predictedPeak(const Params& x, const FitData& d, double exposure, bool sheen) {  // x[11]: its F0
  const Vec3 n = normalOf(x[5], x[6]);
  double peak = 0;
  for (std::size_t i = 0; i < d.checkLights.size(); ++i) {
    const Lobes L = lobes(x[4], x[10], sheen, x[11], n, d.checkLights[i], d.checkViews[i], exposure);
    for (int c = 0; c < 3; ++c) peak = std::max(peak, valueOf(L, x, c));
  }
  return peak;
}
}  // namespace

TexelParams fitTexel(const FitData& d, std::size_t texel, double exposure, const FitOptions& options,
                     double* costOut, bool* refittedOut) {
  const std::size_t n = d.count();
  Texel t{d.lights.data(), d.views.data(), d.values.data() + texel * n * 3, n, exposure,
          std::tan(options.maxTiltDeg * kPi / 180), options.minRoughness, options.sheen, options.specular};
  // Starts (a rough and a glossy surface, flat, dielectric) a few steps each; the best one goes
  // on. A single start falls into another's basin on a fair share of texels.
  Params best{};
  double bestCost = INFINITY;
  // With sheen, each start also tries a tight and a broad sheen lobe (a small sheen colour, so
  // its roughness has a gradient from the first step).
  const std::vector<double> sheenStarts = options.sheen ? std::vector<double>{0.3, 0.7} : std::vector<double>{0};
  for (double roughness : {0.7, 0.3})
    for (double sheenRoughness : sheenStarts) {
      const double sheen = options.sheen ? 0.1 : 0;
      Params x{0.5, 0.5, 0.5, 0, roughness, 0, 0, sheen, sheen, sheen, sheenRoughness, kDielectricF0};
      t.clamp(x);
      t.solveBaseColor(x);
      const double c = levenbergMarquardt(t, x, 5);
      if (c < bestCost) bestCost = c, best = x;
    }
  bestCost = levenbergMarquardt(t, best, options.iterations);
  bool refitted = false;
  if (!d.checkLights.empty()) {
    const double limit = kPeakMargin * d.texelMax[texel];
    for (double floor : kRoughnessFloors) {
      if (predictedPeak(best, d, exposure, options.sheen) <= limit || floor <= t.minRoughness) break;
      t.minRoughness = floor;
      t.clamp(best);
      bestCost = levenbergMarquardt(t, best, options.iterations);
      refitted = true;
    }
  }
  if (costOut) *costOut = bestCost;
  if (refittedOut) *refittedOut = refitted;
  TexelParams p;
  p.brdf.baseColor = {best[0], best[1], best[2]};
  p.brdf.metallic = best[3];
  p.brdf.roughness = best[4];
  p.normal = normalOf(best[5], best[6]);
  p.brdf.sheenColor = {best[7], best[8], best[9]};
  p.brdf.sheenRoughness = best[10];
  p.brdf.specularF0 = best[11];
  return p;
}

FitData gatherFitData(int width, int height, const std::vector<Direction>& lights, const std::vector<Direction>& views,
                      const ImageSource& source, const FitOptions& options) {
  FitData d;
  d.width = width, d.height = height;
  const int images = static_cast<int>(lights.size() * views.size());
  std::vector<int> all(images);
  std::iota(all.begin(), all.end(), 0);
  if (images > options.samples) {  // a partial Fisher-Yates shuffle: the first `samples` of a random order
    SplitMix64 rng(options.seed ^ 0x67c7f17a11ull);
    for (int i = 0; i < options.samples; ++i) std::swap(all[i], all[i + rng.below(images - i)]);
    all.resize(options.samples);
    std::sort(all.begin(), all.end());
  }
  d.images = all;
  std::vector<int> check(images);
  std::iota(check.begin(), check.end(), 0);
  if (images > kPeakCheckPairs) {
    SplitMix64 rng(options.seed ^ 0x9eacc4ec5ull);
    for (int i = 0; i < kPeakCheckPairs; ++i) std::swap(check[i], check[i + rng.below(images - i)]);
    check.resize(kPeakCheckPairs);
  }
  for (int index : check) {
    const auto l = lights[index / views.size()].unitVector(), v = views[index % views.size()].unitVector();
    d.checkLights.push_back({l[0], l[1], l[2]});
    d.checkViews.push_back({v[0], v[1], v[2]});
  }
  const std::size_t texels = static_cast<std::size_t>(width) * height, n = d.images.size();
  d.values.assign(texels * n * 3, 0.f);
  d.texelMax.assign(texels, 0.f);
  std::vector<float> image(texels * 3);
  // Every image once: the fit's samples are kept, and each texel's largest value is noted.
  Progress bar("glTF fit: reading images", images, options.progress);
  std::size_t next = 0;
  for (int index = 0; index < images; ++index) {
    source(index, image.data());
    for (std::size_t t = 0; t < texels; ++t)
      d.texelMax[t] = std::max({d.texelMax[t], image[3 * t], image[3 * t + 1], image[3 * t + 2]});
    if (next < n && d.images[next] == index) {
      const auto l = lights[index / views.size()].unitVector(), v = views[index % views.size()].unitVector();
      d.lights.push_back({l[0], l[1], l[2]});
      d.views.push_back({v[0], v[1], v[2]});
      for (std::size_t t = 0; t < texels; ++t)
        for (int c = 0; c < 3; ++c) d.values[(t * n + next) * 3 + c] = image[3 * t + c];
      ++next;
    }
    bar.advance();
  }
  bar.finish();
  return d;
}

double chooseExposure(const FitData& d) {
  const std::size_t texels = static_cast<std::size_t>(d.width) * d.height, n = d.count();
  std::vector<double> albedo(texels, 0);
  for (std::size_t t = 0; t < texels; ++t) {
    double num = 0, den = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const double cosL = std::max(0.0, d.lights[i][2]);
      double mean = 0;
      for (int c = 0; c < 3; ++c) mean = std::max(mean, double(d.values[(t * n + i) * 3 + c]));
      num += mean * cosL, den += cosL * cosL;
    }
    albedo[t] = den > 0 ? num / den : 0;  // value = albedo x cos(theta_l) by least squares (brightest channel)
  }
  const std::size_t q = std::min(texels - 1, static_cast<std::size_t>(0.99 * texels));
  std::nth_element(albedo.begin(), albedo.begin() + q, albedo.end());
  return std::max(kPi, kPi * albedo[q] / 0.95);
}

GltfMaterial fitMaterial(const FitData& d, double exposure, const FitOptions& options, FitSummary* summary) {
  const auto start = std::chrono::steady_clock::now();
  GltfMaterial m;
  m.width = d.width, m.height = d.height, m.exposure = exposure;
  const std::size_t texels = static_cast<std::size_t>(d.width) * d.height, n = d.count();
  m.texels.resize(texels);
  std::vector<double> costs(texels, 0);
  std::vector<char> refitted(texels, 0);
  Progress bar("glTF fit: texels", texels, options.progress);
  parallelFor(
      texels,
      [&](std::size_t begin, std::size_t end) {
        for (std::size_t t = begin; t < end; ++t) {
          bool wider = false;
          m.texels[t] = fitTexel(d, t, exposure, options, &costs[t], &wider);
          refitted[t] = wider;
          bar.advance();
        }
      },
      16);
  bar.finish();
  if (summary) {
    summary->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    summary->texels = static_cast<int>(texels);
    const double total = std::accumulate(costs.begin(), costs.end(), 0.0);
    summary->sampleRmse = n ? std::sqrt(total / (double(texels) * n * 3)) : 0;
    summary->refitted = static_cast<int>(std::count(refitted.begin(), refitted.end(), 1));
  }
  return m;
}

}  // namespace nbtf::gltf
