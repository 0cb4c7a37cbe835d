// The renderer: one camera sample = a primary ray, a shadow ray towards the light and the
// material's radiance (render/scene.h), batched per image tile into the material source.
//
// Sampling (adaptive oversampling by forward-mode automatic differentiation):
//   Uniform N:  N x N samples on a regular grid in every pixel, averaged.
//   Adaptive:   every pixel's central ray is traced with derivatives (Dual) with respect
//               to the image-plane position. The pixel is split into 3 x 3 sub-pixels when,
//               over its footprint (the central value extrapolated to first order to the
//               footprint's corners), any of these may change:
//                 silhouette  a hit-or-miss condition of a shape (render/shapes.h), or which
//                             shape is nearest (their depth ranges overlap);
//                 terminator  the sign of n.l (the light's horizon on the surface);
//                 shadow      a hit-or-miss condition of an occluder along the shadow ray,
//                             traced with the hit point's derivatives;
//                 corners     the shadow rule for what derivatives cannot see: plain shadow
//                             rays from the hit point extrapolated to the 4 footprint corners
//                             (P + dP/dx ox + dP/dy oy); any answer different from the
//                             central ray's refines;
//                 texture     the footprint, mapped to texel space to first order, covers
//                             other texels than the centre's and the radiance with one of
//                             them (decoded in the central ray's directions) differs from
//                             the centre's by more than `threshold` (any channel), or it
//                             covers 3 or more texels along u or v (minified).
//               A sample that is not split takes the footprint's mean over the texels it
//               covers, weighted by their shares (footprintFilter; else its centre value).
//               Sub-pixels are traced the same way with a third of the footprint, down to
//               `levels` levels (1: 3 x 3, 2: 9 x 9 at most); the last level's sub-pixels are
//               plain rays. A pixel is the mean of its sub-pixels.
// Images are deterministic: each sample depends only on its position, so neither the
// thread count nor the tiling changes a value.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "render/camera.h"
#include "render/material_source.h"
#include "render/scene.h"

namespace nbtf {

enum class SamplingMode { Adaptive, Uniform };

struct RenderOptions {
  int width = 320, height = 240;
  SamplingMode mode = SamplingMode::Adaptive;
  int uniform = 1;          // Uniform: N x N samples per pixel
  int levels = 2;           // Adaptive: levels of 3 x 3 refinement (1 or 2)
  double threshold = 0.08;  // Adaptive: texture test, linear radiance
  bool derivativeTests = true;  // silhouette, terminator and shadow tests from derivatives
  bool shadowCorners = true;    // the corner shadow rule
  bool textureTest = true;
  // Adaptive: a sample that is not split takes the footprint's mean predicted by the texture
  // test (the texels its first-order footprint covers, weighted by their shares) instead of
  // its centre's value: a box filter of the texture from the derivatives.
  bool footprintFilter = true;
  bool progress = true;
  int tile = 16;            // pixels per tile side (the unit of work and of batching)
};

enum RefineReason : std::uint8_t {
  kRefineSilhouette = 1,
  kRefineTerminator = 2,
  kRefineShadow = 4,
  kRefineShadowCorner = 8,
  kRefineTexture = 16,
};
constexpr int kRefineReasons = 5;
const char* refineReasonName(int bit);  // "silhouette", "terminator", "shadow", "shadow-corner", "texture"

struct RenderStats {
  std::uint64_t derivativeRays = 0;    // camera samples traced with derivatives
  std::uint64_t plainRays = 0;         // camera samples traced plain
  std::uint64_t shadowRays = 0;        // shadow rays of camera samples (one per lit sample)
  std::uint64_t cornerShadowRays = 0;  // the corner rule's extra shadow rays
  std::uint64_t materialQueries = 0;   // material evaluations (incl. the texture test's)
  std::uint64_t pixels = 0, refinedPixels = 0, refinedTwice = 0;
  std::uint64_t reasons[kRefineReasons] = {};  // samples refined for each reason
  double seconds = 0;
};

struct RenderResult {
  int width = 0, height = 0;
  std::vector<float> rgb;              // linear radiance, interleaved, top row first
  std::vector<std::uint8_t> refined;   // per pixel: 0, 1 (split once), 2 (a sub-pixel split again)
  std::vector<float> coverage;         // per pixel: fraction of the pixel on the BTF material
  RenderStats stats;
};

// The largest render, per side.
inline constexpr int kMaxRenderSide = 16384;
void checkRenderOptions(const RenderOptions& options);
RenderResult renderImage(const Scene& scene, const Camera& camera, const MaterialSource& material,
                         const RenderOptions& options);

// The measured cost of a camera sample with derivatives (including the adaptive tests and
// their extra material queries) relative to a plain one, on this scene: `samples` pixel
// centres spread over the image, traced and shaded both ways on one thread, best of 3.
struct RayCost {
  int samples = 0;
  double plainSeconds = 0, derivativeSeconds = 0;
  double ratio = 1;  // derivativeSeconds / plainSeconds
};
RayCost measureRayCost(const Scene& scene, const Camera& camera, const MaterialSource& material,
                       const RenderOptions& options, int samples = 4096);

}  // namespace nbtf
