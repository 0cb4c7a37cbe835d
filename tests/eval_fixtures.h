// Synthetic materials and reconstructions for the evaluation tests: a BtfStack built in
// memory with direction-dependent shading, and reconstructions that are the reference
// blurred, scaled or broken in known ways.
#pragma once
#include <cmath>
#include <vector>

#include "eval/blur.h"
#include "eval/evaluate.h"
#include "io/btf_stack.h"

namespace nbtf::testing {

// Linear value of texel (x, y), channel c under light l / view v: a texture times a
// smooth, direction-dependent shading, in [0.02, 0.9].
inline float syntheticValue(const Direction& l, const Direction& v, int x, int y, int c) {
  const double deg = 3.14159265358979323846 / 180;
  double texture = 0.55 + 0.35 * std::sin(1.3 * x + 0.7 * y + 2.0 * c) * std::cos(0.45 * x - 0.9 * y);
  double shading = std::cos(l.thetaDeg * deg) * (0.6 + 0.4 * std::cos(v.thetaDeg * deg)) *
                   (0.8 + 0.2 * std::cos((l.phiDeg - v.phiDeg) * deg));
  return static_cast<float>(0.02 + 0.85 * texture * shading);
}

inline BtfStack syntheticStack(const std::vector<Direction>& lights, const std::vector<Direction>& views, int w, int h,
                               SampleType type = SampleType::Half) {
  BtfStack s(lights, views, w, h, type);
  std::vector<float> img(static_cast<std::size_t>(w) * h * 3);
  for (int l = 0; l < s.numLights(); ++l)
    for (int v = 0; v < s.numViews(); ++v) {
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
          for (int c = 0; c < 3; ++c)
            img[(static_cast<std::size_t>(y) * w + x) * 3 + c] = syntheticValue(lights[l], views[v], x, y, c);
      s.setImageLinear(s.imageIndex(l, v), img.data());
    }
  s.source = "synthetic";
  return s;
}

// Reconstruction = the reference blurred with `sigma` (clamped borders), times a gain that
// grows with the view elevation (so error depends on direction).
inline std::function<void(int, float*)> blurredReconstruction(const BtfStack& ref, double sigma, double gainAt75 = 0.0) {
  return [&ref, sigma, gainAt75](int image, float* out) {
    std::vector<float> src(static_cast<std::size_t>(ref.numTexels()) * 3);
    ref.imageLinear(image, src.data());
    gaussianBlur(src.data(), ref.width(), ref.height(), sigma, BlurBorder::Clamp, out);
    double theta = ref.views()[static_cast<std::size_t>(image % ref.numViews())].thetaDeg;
    float gain = static_cast<float>(1.0 + gainAt75 * theta / 75.0);
    for (std::size_t i = 0; i < src.size(); ++i) out[i] *= gain;
  };
}

}  // namespace nbtf::testing
