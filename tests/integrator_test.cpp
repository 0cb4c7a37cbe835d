// The integrator's adaptive sampler (render/integrator.h): silhouette pixels are refined and the
// interior is not; texel boundaries with a change of colour are detected; shadow edges are caught
// by the derivative test and by the corner rule; images are deterministic.
#include <gtest/gtest.h>

#include "render/integrator.h"
#include "render/scene.h"
#include "render_fixtures.h"
#include "util/parallel.h"

namespace nbtf {
namespace {

using testing::CheckerMaterial;
using testing::ConstantMaterial;

RenderOptions adaptiveOptions(int w, int h, int levels = 1) {
  RenderOptions o;
  o.width = w, o.height = h;
  o.mode = SamplingMode::Adaptive;
  o.levels = levels;
  o.progress = false;
  return o;
}

// The BTF square alone (no occluder, no ground).
Scene squareOnly(double tiling = 1) {
  Scene s = makeScene("plane", tiling);
  s.shapes.resize(1);
  return s;
}

// Which of the pixel's 5 x 5 sample points the predicate holds at: all, none or some.
template <class F>
int agreement(int i, int j, const F& f) {
  int yes = 0;
  for (int b = 0; b < 5; ++b)
    for (int a = 0; a < 5; ++a) yes += f(i + a / 4.0, j + b / 4.0) ? 1 : 0;
  return yes == 0 ? 0 : yes == 25 ? 2 : 1;  // 0 none, 2 all, 1 mixed
}

TEST(RenderAdaptive, RefinesSilhouettePixelsNotTheInterior) {
  const Scene scene = squareOnly();
  const RenderOptions o = adaptiveOptions(64, 48);
  const Camera cam(scene.camera, o.width, o.height);
  const ConstantMaterial material(0.5f);
  const RenderResult r = renderImage(scene, cam, material, o);
  int edges = 0, interior = 0;
  for (int j = 0; j < o.height; ++j)
    for (int i = 0; i < o.width; ++i) {
      const int a = agreement(i, j, [&](double x, double y) { return testing::nearestShape(scene, cam, x, y) == 0; });
      const bool refined = r.refined[static_cast<std::size_t>(j) * o.width + i] > 0;
      if (a == 1) {
        ++edges;
        EXPECT_TRUE(refined) << "edge pixel " << i << "," << j << " not refined";
      } else if (a == 2 && agreement(i - 1, j - 1, [&](double x, double y) {
                             return testing::nearestShape(scene, cam, x, y) == 0 &&
                                    testing::nearestShape(scene, cam, x + 1, y + 1) == 0;
                           }) == 2) {
        ++interior;
        EXPECT_FALSE(refined) << "interior pixel " << i << "," << j << " refined";
      }
    }
  EXPECT_GT(edges, 100);
  EXPECT_GT(interior, 600);
  EXPECT_LT(r.stats.refinedPixels, static_cast<std::uint64_t>(2 * edges));
  EXPECT_GT(r.stats.reasons[0], 0u);  // silhouette
  EXPECT_EQ(r.stats.reasons[4], 0u);  // a constant material has no texture change
}

TEST(RenderAdaptive, SecondLevelRefinesOnlyAlongTheEdge) {
  const Scene scene = squareOnly();
  const Camera cam(scene.camera, 64, 48);
  const ConstantMaterial material(0.5f);
  const RenderResult one = renderImage(scene, cam, material, adaptiveOptions(64, 48, 1));
  const RenderResult two = renderImage(scene, cam, material, adaptiveOptions(64, 48, 2));
  EXPECT_EQ(one.stats.refinedPixels, two.stats.refinedPixels);
  EXPECT_GT(two.stats.refinedTwice, one.stats.refinedPixels / 2);
  // Level 2 splits only some of the 9 sub-pixels: far fewer rays than 81 per refined pixel.
  EXPECT_LT(two.stats.plainRays, 5 * 9 * two.stats.refinedTwice);
}

TEST(RenderAdaptive, DetectsTextureBoundaries) {
  const Scene scene = squareOnly();
  const RenderOptions o = adaptiveOptions(64, 48);
  const Camera cam(scene.camera, o.width, o.height);
  const CheckerMaterial checker(2);
  const RenderResult r = renderImage(scene, cam, checker, o);
  int boundary = 0, flat = 0;
  for (int j = 0; j < o.height; ++j)
    for (int i = 0; i < o.width; ++i) {
      const bool onSquare =
          agreement(i, j, [&](double x, double y) { return testing::nearestShape(scene, cam, x, y) == 0; }) == 2;
      if (!onSquare) continue;
      const int a = agreement(i, j, [&](double x, double y) {
        SurfaceHit<double> h;
        testing::nearestShape(scene, cam, x, y, &h);
        return checker.valueOf(h.u, h.v) > 0.5f;
      });
      const bool refined = r.refined[static_cast<std::size_t>(j) * o.width + i] > 0;
      if (a == 1) {
        ++boundary;
        EXPECT_TRUE(refined) << "texel boundary pixel " << i << "," << j << " not refined";
      } else {
        ++flat;
        // Away from the boundary and the silhouette nothing changes.
        const bool nearBoundary = agreement(i - 1, j - 1, [&](double x, double y) {
                                    SurfaceHit<double> h0, h1;
                                    const bool a0 = testing::nearestShape(scene, cam, x, y, &h0) == 0;
                                    const bool a1 = testing::nearestShape(scene, cam, x + 1, y + 1, &h1) == 0;
                                    return a0 && a1 && checker.valueOf(h0.u, h0.v) == checker.valueOf(h1.u, h1.v) &&
                                           checker.valueOf(h0.u, h0.v) == checker.valueOf(h0.u + 0.01, h0.v) ;
                                  }) != 2;
        if (!nearBoundary) {
          EXPECT_FALSE(refined) << "flat pixel " << i << "," << j << " refined";
        }
      }
    }
  EXPECT_GT(boundary, 40);
  EXPECT_GT(flat, 600);
  EXPECT_GT(r.stats.reasons[4], 0u);
  // The same square with a material that does not change refines only the silhouette.
  const ConstantMaterial constant(0.5f, 2, 2);
  const RenderResult c = renderImage(scene, cam, constant, o);
  EXPECT_LT(c.stats.refinedPixels + static_cast<std::uint64_t>(boundary) / 2, r.stats.refinedPixels);
}

TEST(RenderAdaptive, TextureThresholdIgnoresSmallChanges) {
  const Scene scene = squareOnly();
  RenderOptions o = adaptiveOptions(64, 48);
  const Camera cam(scene.camera, o.width, o.height);
  const CheckerMaterial faint(2, 0.500f, 0.504f);  // x sun (1) = 0.004 < threshold 0.01
  const RenderResult r = renderImage(scene, cam, faint, o);
  EXPECT_EQ(r.stats.reasons[4], 0u);
  o.threshold = 0.001;
  EXPECT_GT(renderImage(scene, cam, faint, o).stats.reasons[4], 0u);
}

TEST(RenderAdaptive, FootprintFilterAveragesTexelsOfUnsplitPixels) {
  // Texel contrast below the threshold: nothing is split for texture; with the filter the
  // unsplit pixels take the mean of the texels their footprint covers, which is closer to
  // uniform 9 x 9 than the centre's value.
  const Scene scene = squareOnly(1);
  RenderOptions o = adaptiveOptions(48, 36);
  o.threshold = 0.05;
  const Camera cam(scene.camera, o.width, o.height);
  const CheckerMaterial checker(8, 0.40f, 0.43f);
  RenderOptions u = o;
  u.mode = SamplingMode::Uniform;
  u.uniform = 9;
  const RenderResult ref = renderImage(scene, cam, checker, u);
  const RenderResult filtered = renderImage(scene, cam, checker, o);
  o.footprintFilter = false;
  const RenderResult centre = renderImage(scene, cam, checker, o);
  EXPECT_EQ(filtered.stats.reasons[4], 0u);
  EXPECT_EQ(filtered.refined, centre.refined);  // the same decisions
  double ef = 0, ec = 0;  // over the unsplit pixels (split ones are equal in both)
  for (std::size_t i = 0; i < ref.rgb.size(); ++i) {
    if (filtered.refined[i / 3]) {
      EXPECT_EQ(filtered.rgb[i], centre.rgb[i]);
      continue;
    }
    ef += (filtered.rgb[i] - ref.rgb[i]) * (filtered.rgb[i] - ref.rgb[i]);
    ec += (centre.rgb[i] - ref.rgb[i]) * (centre.rgb[i] - ref.rgb[i]);
  }
  EXPECT_GT(ec, 0.01);
  EXPECT_LT(ef, 0.2 * ec);
}

// Pixels on the shadow edge cast by the occluder onto the square.
struct ShadowPixels {
  std::vector<std::size_t> edge, lit;
};
ShadowPixels shadowPixels(const Scene& scene, const Camera& cam) {
  ShadowPixels s;
  for (int j = 0; j < cam.height(); ++j)
    for (int i = 0; i < cam.width(); ++i) {
      const bool onSquare = agreement(i, j, [&](double x, double y) { return testing::nearestShape(scene, cam, x, y) == 0; }) == 2;
      if (!onSquare) continue;
      const int a = agreement(i, j, [&](double x, double y) { return testing::directlyLit(scene, cam, x, y); });
      if (a == 1) s.edge.push_back(static_cast<std::size_t>(j) * cam.width() + i);
    }
  return s;
}

TEST(RenderAdaptive, ShadowEdgesRefinedByDerivativesAndByTheCornerRule) {
  Scene scene = makeScene("plane", 1);  // square + grey ball above it
  RenderOptions o = adaptiveOptions(96, 72);
  const Camera cam(scene.camera, o.width, o.height);
  const ConstantMaterial material(0.5f);
  const ShadowPixels px = shadowPixels(scene, cam);
  ASSERT_GT(px.edge.size(), 30u);
  auto refinedShare = [&](const RenderResult& r) {
    std::size_t n = 0;
    for (std::size_t p : px.edge) n += r.refined[p] > 0;
    return static_cast<double>(n) / px.edge.size();
  };
  // Both rules: every shadow-edge pixel.
  EXPECT_EQ(refinedShare(renderImage(scene, cam, material, o)), 1.0);
  // The corner rule alone (no derivative tests at all).
  o.derivativeTests = false;
  const RenderResult corners = renderImage(scene, cam, material, o);
  EXPECT_GE(refinedShare(corners), 0.9);
  EXPECT_GT(corners.stats.reasons[3], 0u);
  EXPECT_GT(corners.stats.cornerShadowRays, 0u);
  // The derivative test on the shadow ray alone.
  o.derivativeTests = true;
  o.shadowCorners = false;
  const RenderResult deriv = renderImage(scene, cam, material, o);
  EXPECT_GE(refinedShare(deriv), 0.9);
  EXPECT_GT(deriv.stats.reasons[2], 0u);
  // Neither: the shadow edge is not refined (so the two checks above can fail).
  o.derivativeTests = false;
  EXPECT_LT(refinedShare(renderImage(scene, cam, material, o)), 0.05);
}

TEST(RenderAdaptive, AdaptiveMatchesUniformWhereItRefines) {
  // A refined pixel at level 2 whose sub-pixels were all split equals uniform 9 x 9 there.
  const Scene scene = squareOnly(2);
  const Camera cam(scene.camera, 48, 36);
  const CheckerMaterial checker(4);
  RenderOptions a = adaptiveOptions(48, 36, 2);
  RenderOptions u = a;
  u.mode = SamplingMode::Uniform;
  u.uniform = 9;
  const RenderResult ra = renderImage(scene, cam, checker, a), ru = renderImage(scene, cam, checker, u);
  RenderOptions one = a;
  one.mode = SamplingMode::Uniform;
  one.uniform = 1;
  const RenderResult r1 = renderImage(scene, cam, checker, one);
  double errA = 0, err1 = 0;
  for (std::size_t i = 0; i < ru.rgb.size(); ++i) {
    errA += (ra.rgb[i] - ru.rgb[i]) * (ra.rgb[i] - ru.rgb[i]);
    err1 += (r1.rgb[i] - ru.rgb[i]) * (r1.rgb[i] - ru.rgb[i]);
  }
  EXPECT_LT(errA, 0.05 * err1);  // adaptive is close to 9 x 9, one ray per pixel is not
}

TEST(RenderAdaptive, DeterministicForAFixedThreadCount) {
  const Scene scene = makeScene("sphere", 3);
  RenderOptions o = adaptiveOptions(48, 36, 2);
  o.tile = 8;
  const Camera cam(scene.camera, o.width, o.height);
  const CheckerMaterial checker(8);
  setThreadCount(2);
  const RenderResult a = renderImage(scene, cam, checker, o);
  const RenderResult b = renderImage(scene, cam, checker, o);
  setThreadCount(1);
  const RenderResult c = renderImage(scene, cam, checker, o);
  setThreadCount(0);
  EXPECT_EQ(a.rgb, b.rgb);
  EXPECT_EQ(a.refined, b.refined);
  EXPECT_EQ(a.rgb, c.rgb);  // independent of the thread count as well
  EXPECT_EQ(a.stats.derivativeRays, c.stats.derivativeRays);
}

TEST(RenderAdaptive, EveryScenesRendersAndRefinesAFraction) {
  for (const std::string& name : sceneNames()) {
    const Scene scene = makeScene(name, 2);
    RenderOptions o = adaptiveOptions(48, 36, 2);
    const Camera cam(scene.camera, o.width, o.height);
    const CheckerMaterial checker(16);
    const RenderResult r = renderImage(scene, cam, checker, o);
    EXPECT_GT(r.stats.refinedPixels, 0u) << name;
    EXPECT_LT(r.stats.refinedPixels, r.stats.pixels) << name;
    double covered = 0;
    for (float c : r.coverage) covered += c;
    EXPECT_GT(covered, 0.1 * r.stats.pixels) << name << ": the object fills part of the image";
  }
}

TEST(RenderAdaptive, RayCostIsMeasured) {
  const Scene scene = makeScene("sphere", 1);
  const RenderOptions o = adaptiveOptions(48, 36, 2);
  const Camera cam(scene.camera, o.width, o.height);
  const CheckerMaterial checker(8);
  const RayCost c = measureRayCost(scene, cam, checker, o, 256);
  // The count of timed samples; the times and their ratio are the benchmark's
  // (scripts/bench_render.sh): a loaded machine can make either kind of ray the slower.
  EXPECT_GT(c.samples, 200);
}

}  // namespace
}  // namespace nbtf
