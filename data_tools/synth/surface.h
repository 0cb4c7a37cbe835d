// The meso-structure sampled on a fine grid (supersampling x supersampling samples per
// texel), with what shading needs at every sample, and ray marching over the height
// field. The grid wraps at its borders: the pattern is periodic, so rays that leave
// one side re-enter on the other, exactly as on an endless tiled sample.
//
// Frame: x = image right, y = image up, z = out of the surface (right-handed). A light
// or view Direction (theta, phi) maps to (sin t cos p, sin t sin p, cos t): phi = 0
// points to the image's right, phi = 90 to its top.
#pragma once
#include <cstddef>
#include <vector>

#include "synth/meso_pattern.h"

namespace nbtf::synth {

// What shading needs at one fine sample.
struct ShadingPoint {
  float normal[3], tangent[3], bitangent[3];  // orthonormal; tangent = fibre direction
  float albedo[3];
  float wardWeight;                // ks / (4 alphaT alphaB)
  float invAlphaT2, invAlphaB2;    // 1 / alpha^2 along / across the fibres
  float sheenWeight;               // sheen * (2 + 1/r) / 2  (the Charlie lobe times pi)
  float sheenHalfExponent;         // 1 / (2 r): sin(theta_h)^(1/r) = (1 - cos^2)^(1/(2r))
  float occlusion;                 // 1 - cosine-weighted sky visibility
};

class Surface {
 public:
  Surface(const MesoPattern& pattern, int width, int height, int supersampling);

  int width() const { return width_; }
  int height() const { return height_; }
  int supersampling() const { return ss_; }
  int fineWidth() const { return fineW_; }
  int fineHeight() const { return fineH_; }
  std::size_t numSamples() const { return points_.size(); }
  const ShadingPoint& point(std::size_t sample) const { return points_[sample]; }
  float sampleHeight(std::size_t sample) const { return heights_[sample]; }
  float minHeight() const { return minHeight_; }
  float maxHeight() const { return maxHeight_; }
  // The plane the image is rectified to (the mean height): a point at this height shows
  // at the same texel from every view; higher points shift away from the viewer.
  float referenceHeight() const { return referenceHeight_; }
  const float* meanAlbedo() const { return meanAlbedo_; }

  // Height (texels) at fine-grid coordinates (column, row), bilinear, wrapping.
  float heightAt(double column, double row) const;
  // Soft visibility in [0, 1] of the distant direction `dir` (unit, frame above) from
  // fine sample `sample`: 0 when the height field blocks it, with a penumbra of about
  // 1 / hardness radians.
  float visibility(std::size_t sample, const double dir[3], float hardness) const;
  // The fine sample hit first by the view ray that crosses the reference plane at fine
  // sample `sample`, travelling along -view (parallax and masking in one).
  std::size_t parallaxHit(std::size_t sample, const double view[3]) const;

 private:
  float skyVisibility(std::size_t sample) const;

  int width_, height_, ss_, fineW_, fineH_;
  std::vector<float> heights_;
  std::vector<ShadingPoint> points_;
  float minHeight_ = 0, maxHeight_ = 0, referenceHeight_ = 0;
  float meanAlbedo_[3] = {0, 0, 0};
};

}  // namespace nbtf::synth
