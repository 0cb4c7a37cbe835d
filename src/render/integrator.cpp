#include "render/integrator.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <type_traits>

#include "util/error.h"
#include "util/parallel.h"
#include "util/progress.h"
#include "util/timer.h"

namespace nbtf {

const char* refineReasonName(int bit) {
  static const char* names[kRefineReasons] = {"silhouette", "terminator", "shadow", "shadow-corner", "texture"};
  return bit >= 0 && bit < kRefineReasons ? names[bit] : "?";
}

void checkRenderOptions(const RenderOptions& o) {
  if (o.width < 1 || o.height < 1 || o.width > kMaxRenderSide || o.height > kMaxRenderSide)
    throw Error("--size must be between 1x1 and " + std::to_string(kMaxRenderSide) + "x" +
                std::to_string(kMaxRenderSide) + ", got " + std::to_string(o.width) + "x" + std::to_string(o.height));
  if (o.mode == SamplingMode::Uniform && (o.uniform < 1 || o.uniform > 64))
    throw Error("--uniform N must be in 1..64, got " + std::to_string(o.uniform));
  if (o.mode == SamplingMode::Adaptive && (o.levels < 1 || o.levels > 3))
    throw Error("--levels must be 1, 2 or 3, got " + std::to_string(o.levels));
  if (!(o.threshold >= 0) || !std::isfinite(o.threshold))
    throw Error("--threshold must be a number >= 0");
  if (o.tile < 1) throw Error("tile size must be >= 1");
}

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kShadowOffset = 1e-4;

struct LocalStats {
  std::uint64_t derivativeRays = 0, plainRays = 0, shadowRays = 0, cornerShadowRays = 0, materialQueries = 0;
  std::uint64_t reasons[kRefineReasons] = {};
};

// One camera sample between tracing and shading: its radiance is base + sunW * material at
// query qSun + envW * material at query qEnv; the texture test predicts the footprint's mean
// from those (the centre's texel, share centreShare) and the other texels' queries from
// cornerBegin on (perTexel per texel, shares share[k]).
struct SampleRecord {
  float base[3] = {0, 0, 0};
  float sunW = 0, envW = 0;
  int qSun = -1, qEnv = -1;
  int cornerBegin = 0, cornerCount = 0, perTexel = 1;  // other texels' queries: (sun,) env each
  float centreShare = 1, share[3] = {0, 0, 0};  // footprint shares of the centre's and the other texels
  std::uint8_t reasons = 0;
  bool onBtf = false;
};

class SampleTracer {
 public:
  SampleTracer(const Scene& scene, const MaterialSource& material, const RenderOptions& options)
      : scene_(scene), options_(options), texW_(material.width()), texH_(material.height()) {}

  // Any shape between `origin` and the light (plain).
  bool occluded(const Vec3d& origin) const {
    const Ray<double> ray{origin, scene_.toLight};
    for (const Shape& s : scene_.shapes)
      if (intersectShape<double>(s, ray, kShadowOffset, kInf, nullptr)) return true;
    return false;
  }

  template <class T>
  void trace(const Ray<T>& ray, double half, SampleRecord& rec, std::vector<UvQuery>& queries, LocalStats& st) const {
    constexpr bool kDual = std::is_same_v<T, Dual>;
    const bool tests = kDual && options_.derivativeTests;
    SurfaceHit<T> hit;
    const int best = nearestHit(ray, half, tests, hit, rec);
    if (best < 0) {
      rec.base[0] = rec.base[1] = rec.base[2] = static_cast<float>(scene_.env);
      return;
    }
    const Shape& shape = scene_.shapes[best];
    // ---- Local frame (two-sided: the normal faces the viewer).
    Vec3<T> n = hit.n;
    if (val(dot(ray.dir, n)) > 0) n = -n;
    const Vec3<T> tx = normalize(hit.tu - n * dot(n, hit.tu));
    const Vec3<T> ty = cross(n, tx);
    const Vec3d& L = scene_.toLight;
    const T lz = dot(n, L);
    if (tests && mayCross(lz, 0.0, half)) rec.reasons |= kRefineTerminator;
    const bool lit = val(lz) > 0;
    bool direct = false;
    if (lit) {
      ++st.shadowRays;
      direct = !shadowed(Ray<T>{hit.p + n * kShadowOffset, Vec3<T>(L)}, half, tests, rec);
    }
    if (kDual && options_.shadowCorners && (lit || (rec.reasons & kRefineTerminator)))
      testShadowCorners(hit, n, half, direct, rec, st);
    // ---- Material.
    if (shape.material != 0) {
      const double e = scene_.albedo * (scene_.sun * (direct ? val(lz) : 0.0) + scene_.env);
      rec.base[0] = rec.base[1] = rec.base[2] = static_cast<float>(e);
      return;
    }
    rec.onBtf = true;
    addMaterialQueries(ray, hit, n, tx, ty, lz, direct, rec, queries);
    if (kDual && options_.textureTest) testTexture(hit, half, direct, rec, queries);
  }

  // Radiance and the texture decision once the queries are evaluated. Material values are
  // clamped at 0 (radiance is not negative; a network may undershoot slightly).
  void finish(SampleRecord& rec, const float* rgb, float* out) const {
    auto at = [&](int q, int c) { return std::max(0.0f, rgb[3 * q + c]); };
    for (int c = 0; c < 3; ++c) {
      const float sun = rec.qSun >= 0 ? at(rec.qSun, c) : 0.0f, env = rec.qEnv >= 0 ? at(rec.qEnv, c) : 0.0f;
      const float centre = rec.base[c] + rec.sunW * sun + rec.envW * env;
      out[c] = centre;
      if (rec.cornerCount == 0) continue;
      // Split when any other texel the footprint covers differs from the centre's by more
      // than the threshold; otherwise the footprint's mean predicted from the texels it
      // covers (first order) is the sample's value.
      float mean = rec.centreShare * centre;
      for (int k = 0; k < rec.cornerCount; ++k) {
        const int q = rec.cornerBegin + k * rec.perTexel;
        const float other = rec.base[c] + (rec.perTexel == 2 ? rec.sunW * at(q, c) : 0.0f) +
                            rec.envW * at(q + rec.perTexel - 1, c);
        if (std::fabs(other - centre) > options_.threshold) rec.reasons |= kRefineTexture;
        mean += rec.share[k] * other;
      }
      if (options_.footprintFilter) out[c] = mean;
    }
  }

 private:
  // The nearest shape `ray` hits (-1: none), its hit in `bestHit`, with the silhouette tests.
  template <class T>
  int nearestHit(const Ray<T>& ray, double half, bool tests, SurfaceHit<T>& bestHit, SampleRecord& rec) const {
    const int count = static_cast<int>(scene_.shapes.size());
    int best = -1;
    double bestT = kInf, bestSpread = 0;
    double hitT[8], hitSpread[8];
    bool hitAny[8];
    EdgeProbe probes[8];
    for (int i = 0; i < count && i < 8; ++i) {
      probes[i].half = half;
      SurfaceHit<T> h;
      hitAny[i] = intersectShape(scene_.shapes[i], ray, 1e-6, kInf, &h, tests ? &probes[i] : nullptr);
      if (!hitAny[i]) continue;
      hitT[i] = val(h.t), hitSpread[i] = spread(h.t, half);
      if (hitT[i] < bestT) best = i, bestT = hitT[i], bestSpread = hitSpread[i], bestHit = h;
    }
    if (tests) {
      for (int i = 0; i < count && i < 8; ++i) {
        // An event hidden behind a surely hit nearer surface cannot show (the adaptive-oversampling paper, 3.5).
        if (probes[i].edge && (best < 0 || probes[i].depth <= bestT + bestSpread)) rec.reasons |= kRefineSilhouette;
        if (i != best && best >= 0 && hitAny[i] && hitT[i] - hitSpread[i] <= bestT + bestSpread)
          rec.reasons |= kRefineSilhouette;
      }
    }
    return best;
  }

  // Whether a shape blocks the shadow ray, traced with the hit point's derivatives.
  template <class T>
  bool shadowed(const Ray<T>& shadow, double half, bool tests, SampleRecord& rec) const {
    bool blocked = false, surelyBlocked = false, edge = false;
    for (int i = 0; i < static_cast<int>(scene_.shapes.size()); ++i) {
      EdgeProbe probe;
      probe.half = half;
      const bool h = intersectShape<T>(scene_.shapes[i], shadow, kShadowOffset, kInf, nullptr, tests ? &probe : nullptr);
      if (h) blocked = true, surelyBlocked |= !probe.edge;
      edge |= probe.edge;
      if (h && !tests) break;
    }
    if (tests && edge && !surelyBlocked) rec.reasons |= kRefineShadow;
    return blocked;
  }

  // The corner rule: shadow tests from the footprint's corners.
  template <class T>
  void testShadowCorners(const SurfaceHit<T>& hit, const Vec3<T>& n, double half, bool direct, SampleRecord& rec,
                         LocalStats& st) const {
    const Vec3d& L = scene_.toLight;
    const Vec3d nc = val(n);
    for (int k = 0; k < 4 && !(rec.reasons & kRefineShadowCorner); ++k) {
      const double ox = (k & 1) ? half : -half, oy = (k & 2) ? half : -half;
      const Vec3d pc = extrapolate(hit.p, ox, oy);
      const Vec3d ncorner = extrapolate(n, ox, oy);
      bool directC = false;
      if (dot(ncorner, L) > 0) {
        ++st.cornerShadowRays;
        directC = !occluded(pc + nc * kShadowOffset);
      }
      if (directC != direct) rec.reasons |= kRefineShadowCorner;
    }
  }

  // The material queries of a hit on the BTF: the sun's term where it is direct, the
  // environment's always.
  template <class T>
  void addMaterialQueries(const Ray<T>& ray, const SurfaceHit<T>& hit, const Vec3<T>& n, const Vec3<T>& tx,
                          const Vec3<T>& ty, const T& lz, bool direct, SampleRecord& rec,
                          std::vector<UvQuery>& queries) const {
    const Vec3d& L = scene_.toLight;
    const Vec3d txd = val(tx), tyd = val(ty), nd = val(n), wo = -val(ray.dir);
    UvQuery q;
    q.u = static_cast<float>(val(hit.u));
    q.v = static_cast<float>(val(hit.v));
    q.view = {static_cast<float>(dot(wo, txd)), static_cast<float>(dot(wo, tyd)),
              static_cast<float>(std::max(1e-4, dot(wo, nd)))};
    if (direct) {
      q.light = {static_cast<float>(dot(L, txd)), static_cast<float>(dot(L, tyd)), static_cast<float>(val(lz))};
      rec.qSun = static_cast<int>(queries.size());
      rec.sunW = static_cast<float>(scene_.sun);
      queries.push_back(q);
    }
    UvQuery qe = q;
    qe.light = {0, 0, 1};
    rec.qEnv = static_cast<int>(queries.size());
    rec.envW = static_cast<float>(scene_.env);
    queries.push_back(qe);
  }

  // Texture test: which texels the footprint covers.
  template <class T>
  void testTexture(const SurfaceHit<T>& hit, double half, bool direct, SampleRecord& rec,
                   std::vector<UvQuery>& queries) const {
    const T U = hit.u * double(texW_), V = hit.v * double(texH_);
    const double u0 = std::floor(val(U)), v0 = std::floor(val(V));
    const double su = spread(U, half), sv = spread(V, half);
    if (std::floor(val(U) + su) - std::floor(val(U) - su) > 1 || std::floor(val(V) + sv) - std::floor(val(V) - sv) > 1) {
      rec.reasons |= kRefineTexture;  // minified: the footprint covers 3 or more texels along u or v
      return;
    }
    // The footprint, mapped to texel space to first order, covers at most a 2 x 2 block
    // of texels: those its corners reach, or points of a 6 x 6 grid inside it. The share
    // of each (from the grid) weights the material decoded there (both terms, in the
    // central ray's directions) in the footprint's predicted mean.
    rec.cornerBegin = static_cast<int>(queries.size());
    rec.perTexel = direct ? 2 : 1;
    const double ub = std::floor(val(U) - su), vb = std::floor(val(V) - sv);
    int counts[4] = {0, 0, 0, 0};  // texels (ub + i, vb + j) at index 2 j + i
    constexpr int kGrid = 6;
    for (int b = 0; b < kGrid; ++b)
      for (int a = 0; a < kGrid; ++a) {
        const double ox = half * (2.0 * (a + 0.5) / kGrid - 1), oy = half * (2.0 * (b + 0.5) / kGrid - 1);
        const int i = std::clamp(static_cast<int>(std::floor(extrapolate(U, ox, oy)) - ub), 0, 1);
        const int j = std::clamp(static_cast<int>(std::floor(extrapolate(V, ox, oy)) - vb), 0, 1);
        ++counts[2 * j + i];
      }
    bool reached[4] = {false, false, false, false};  // by a footprint corner (share may be ~0)
    for (int k = 0; k < 4; ++k) {
      const double ox = (k & 1) ? half : -half, oy = (k & 2) ? half : -half;
      const int i = std::clamp(static_cast<int>(std::floor(extrapolate(U, ox, oy)) - ub), 0, 1);
      const int j = std::clamp(static_cast<int>(std::floor(extrapolate(V, ox, oy)) - vb), 0, 1);
      reached[2 * j + i] = true;
    }
    const int centre = 2 * std::clamp(static_cast<int>(v0 - vb), 0, 1) + std::clamp(static_cast<int>(u0 - ub), 0, 1);
    rec.centreShare = static_cast<float>(counts[centre]) / (kGrid * kGrid);
    int nOther = 0;
    for (int k = 0; k < 4; ++k) {
      if (k == centre || (counts[k] == 0 && !reached[k])) continue;
      const float cu = static_cast<float>((ub + (k & 1) + 0.5) / texW_), cv = static_cast<float>((vb + (k >> 1) + 0.5) / texH_);
      if (direct) {
        UvQuery c = queries[rec.qSun];
        c.u = cu, c.v = cv;
        queries.push_back(c);
      }
      UvQuery c = queries[rec.qEnv];
      c.u = cu, c.v = cv;
      queries.push_back(c);
      rec.share[nOther++] = static_cast<float>(counts[k]) / (kGrid * kGrid);
    }
    rec.cornerCount = nOther;
  }
  const Scene& scene_;
  const RenderOptions& options_;
  int texW_, texH_;
};

struct Task {
  double px, py, size;
  int level;
  int pixel;            // index within the tile's pixel list
  int childBegin = -1;  // 9 children when split
  float rgb[3];
  float coverage;
};

void countReasons(std::uint8_t reasons, LocalStats& st) {
  for (int b = 0; b < kRefineReasons; ++b)
    if (reasons & (1u << b)) ++st.reasons[b];
}

// Traces tasks [begin, end) (Dual where `dual(task)`), evaluates their queries in one batch.
template <class DualFn>
void traceWave(const SampleTracer& tracer, const Camera& camera, const MaterialSource& material, std::vector<Task>& tasks,
               std::size_t begin, std::size_t end, const DualFn& dual, std::vector<SampleRecord>& records,
               std::vector<UvQuery>& queries, std::vector<float>& rgb, LocalStats& st) {
  records.assign(end - begin, SampleRecord());
  queries.clear();
  for (std::size_t i = begin; i < end; ++i) {
    const Task& t = tasks[i];
    if (dual(t)) {
      ++st.derivativeRays;
      tracer.trace(camera.dualRay(t.px, t.py), 0.5 * t.size, records[i - begin], queries, st);
    } else {
      ++st.plainRays;
      tracer.trace(camera.ray<double>(t.px, t.py), 0.5 * t.size, records[i - begin], queries, st);
    }
  }
  rgb.resize(3 * queries.size());
  if (!queries.empty()) material.evaluate(queries.data(), queries.size(), rgb.data());
  st.materialQueries += queries.size();
  for (std::size_t i = begin; i < end; ++i) {
    SampleRecord& r = records[i - begin];
    tracer.finish(r, rgb.data(), tasks[i].rgb);
    tasks[i].coverage = r.onBtf ? 1.0f : 0.0f;
  }
}

// Pixels [x0, x1) x [y0, y1) of the image.
struct TileBounds {
  int x0, y0, x1, y1;
  int width() const { return x1 - x0; }
};

// n x n samples per pixel, pixel by pixel in row order, each pixel's samples in row order.
std::vector<Task> tileSamples(const TileBounds& b, int n, int level) {
  std::vector<Task> tasks;
  const int tw = b.width();
  for (int y = b.y0; y < b.y1; ++y)
    for (int x = b.x0; x < b.x1; ++x)
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
          Task t;
          t.px = x + (i + 0.5) / n, t.py = y + (j + 0.5) / n, t.size = 1.0 / n;
          t.level = level;
          t.pixel = (y - b.y0) * tw + (x - b.x0);
          tasks.push_back(t);
        }
  return tasks;
}

// Traces the tasks in waves: a task traced with derivatives that has a reason to refine gets
// 9 children (a 3 x 3 grid over its footprint), traced in the next wave.
void traceInWaves(const SampleTracer& tracer, const Camera& camera, const MaterialSource& material,
                  const RenderOptions& options, std::vector<Task>& tasks, LocalStats& st) {
  const bool adaptive = options.mode == SamplingMode::Adaptive;
  std::vector<SampleRecord> records;
  std::vector<UvQuery> queries;
  std::vector<float> rgb;
  auto useDual = [&](const Task& t) { return adaptive && t.level < options.levels; };
  std::size_t begin = 0, end = tasks.size();
  while (begin < end) {
    traceWave(tracer, camera, material, tasks, begin, end, useDual, records, queries, rgb, st);
    for (std::size_t i = begin; i < end; ++i) {
      const std::uint8_t reasons = records[i - begin].reasons;
      if (!useDual(tasks[i]) || !reasons) continue;
      countReasons(reasons, st);
      tasks[i].childBegin = static_cast<int>(tasks.size());
      const Task parent = tasks[i];
      const double s = parent.size / 3;
      for (int j = -1; j <= 1; ++j)
        for (int k = -1; k <= 1; ++k) {
          Task c;
          c.px = parent.px + k * s, c.py = parent.py + j * s, c.size = s;
          c.level = parent.level + 1;
          c.pixel = parent.pixel;
          tasks.push_back(c);
        }
    }
    begin = end;
    end = tasks.size();
  }
}

// Bottom-up: a split task is the mean of its 9 children (which come after it).
void averageChildren(std::vector<Task>& tasks) {
  for (std::size_t i = tasks.size(); i-- > 0;) {
    Task& t = tasks[i];
    if (t.childBegin < 0) continue;
    float acc[3] = {0, 0, 0}, cov = 0;
    for (int c = 0; c < 9; ++c) {
      const Task& ch = tasks[t.childBegin + c];
      for (int k = 0; k < 3; ++k) acc[k] += ch.rgb[k];
      cov += ch.coverage;
    }
    for (int k = 0; k < 3; ++k) t.rgb[k] = acc[k] / 9;
    t.coverage = cov / 9;
  }
}

// Each pixel of the tile: the mean of its n x n samples, and (adaptive) how deep it was refined.
void writeTilePixels(const std::vector<Task>& tasks, const TileBounds& b, int n, bool adaptive, RenderResult& result) {
  const int tw = b.width(), W = result.width;
  const std::size_t pixels = static_cast<std::size_t>(tw) * (b.y1 - b.y0);
  for (std::size_t p = 0; p < pixels; ++p) {
    const int x = b.x0 + static_cast<int>(p % tw), y = b.y0 + static_cast<int>(p / tw);
    const std::size_t out = static_cast<std::size_t>(y) * W + x;
    double acc[3] = {0, 0, 0}, cov = 0;
    const std::size_t nn = static_cast<std::size_t>(n) * n;
    for (std::size_t s = 0; s < nn; ++s) {
      const Task& t = tasks[p * nn + s];
      for (int k = 0; k < 3; ++k) acc[k] += t.rgb[k];
      cov += t.coverage;
    }
    for (int k = 0; k < 3; ++k) result.rgb[3 * out + k] = static_cast<float>(acc[k] / nn);
    result.coverage[out] = static_cast<float>(cov / nn);
    if (adaptive) {
      const Task& t = tasks[p];
      if (t.childBegin >= 0) {
        result.refined[out] = 1;
        for (int c = 0; c < 9; ++c)
          if (tasks[t.childBegin + c].childBegin >= 0) result.refined[out] = 2;
      }
    }
  }
}

// The tiles' counts, and the refined pixels'.
void sumRenderStats(const std::vector<LocalStats>& tileStats, RenderResult& result) {
  RenderStats& s = result.stats;
  for (const LocalStats& st : tileStats) {
    s.derivativeRays += st.derivativeRays;
    s.plainRays += st.plainRays;
    s.shadowRays += st.shadowRays;
    s.cornerShadowRays += st.cornerShadowRays;
    s.materialQueries += st.materialQueries;
    for (int b = 0; b < kRefineReasons; ++b) s.reasons[b] += st.reasons[b];
  }
  s.pixels = static_cast<std::uint64_t>(result.width) * result.height;
  for (std::uint8_t r : result.refined) {
    s.refinedPixels += r > 0;
    s.refinedTwice += r > 1;
  }
}

}  // namespace

RenderResult renderImage(const Scene& scene, const Camera& camera, const MaterialSource& material,
                         const RenderOptions& options) {
  checkRenderOptions(options);
  if (camera.width() != options.width || camera.height() != options.height)
    throw Error("the camera's image size differs from the render options'");
  if (scene.shapes.size() > 8) throw Error("a scene holds at most 8 shapes");
  const auto start = std::chrono::steady_clock::now();
  RenderResult result;
  const int W = options.width, H = options.height;
  result.width = W, result.height = H;
  result.rgb.assign(static_cast<std::size_t>(W) * H * 3, 0.0f);
  result.refined.assign(static_cast<std::size_t>(W) * H, 0);
  result.coverage.assign(static_cast<std::size_t>(W) * H, 0.0f);
  const int tilesX = (W + options.tile - 1) / options.tile, tilesY = (H + options.tile - 1) / options.tile;
  const std::size_t tiles = static_cast<std::size_t>(tilesX) * tilesY;
  SampleTracer tracer(scene, material, options);
  std::vector<LocalStats> tileStats(tiles);
  Progress progress("render", tiles, options.progress);
  const bool adaptive = options.mode == SamplingMode::Adaptive;

  parallelForDynamic(tiles, [&](std::size_t tileIndex, int) {
    const int x0 = static_cast<int>(tileIndex % tilesX) * options.tile, y0 = static_cast<int>(tileIndex / tilesX) * options.tile;
    const TileBounds bounds{x0, y0, std::min(W, x0 + options.tile), std::min(H, y0 + options.tile)};
    const int n = adaptive ? 1 : options.uniform;
    std::vector<Task> tasks = tileSamples(bounds, n, adaptive ? 0 : options.levels);
    traceInWaves(tracer, camera, material, options, tasks, tileStats[tileIndex]);
    averageChildren(tasks);
    writeTilePixels(tasks, bounds, n, adaptive, result);
    progress.advance();
  });
  progress.finish();

  sumRenderStats(tileStats, result);
  result.stats.seconds = secondsSince(start);
  return result;
}

RayCost measureRayCost(const Scene& scene, const Camera& camera, const MaterialSource& material,
                       const RenderOptions& options, int samples) {
  RayCost cost;
  const int W = camera.width(), H = camera.height();
  const double stride = std::max(1.0, std::sqrt(static_cast<double>(W) * H / std::max(1, samples)));
  std::vector<Task> tasks;
  for (double y = 0.5 * stride; y < H; y += stride)
    for (double x = 0.5 * stride; x < W; x += stride) {
      Task t;
      t.px = std::floor(x) + 0.5, t.py = std::floor(y) + 0.5, t.size = 1, t.level = 0, t.pixel = 0;
      tasks.push_back(t);
    }
  cost.samples = static_cast<int>(tasks.size());
  SampleTracer tracer(scene, material, options);
  std::vector<SampleRecord> records;
  std::vector<UvQuery> queries;
  std::vector<float> rgb;
  auto time = [&](bool dual) {
    double best = kInf;
    for (int rep = 0; rep < 3; ++rep) {
      LocalStats st;
      const auto t0 = std::chrono::steady_clock::now();
      traceWave(tracer, camera, material, tasks, 0, tasks.size(), [&](const Task&) { return dual; }, records, queries, rgb, st);
      best = std::min(best, secondsSince(t0));
    }
    return best;
  };
  cost.plainSeconds = time(false);
  cost.derivativeSeconds = time(true);
  cost.ratio = cost.plainSeconds > 0 ? cost.derivativeSeconds / cost.plainSeconds : 1.0;
  return cost;
}

}  // namespace nbtf
