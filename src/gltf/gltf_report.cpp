#include "gltf/gltf_report.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <mutex>

#include "io/ground_truth.h"
#include "io/image_io.h"
#include "util/error.h"
#include "util/parallel.h"
#include "util/progress.h"

namespace nbtf::gltf {
namespace {

constexpr double kBandDeg = 15;
constexpr int kBands = 6;  // 0-15, ..., 75-90

int bandOf(double thetaDeg) { return std::clamp(static_cast<int>(thetaDeg / kBandDeg), 0, kBands - 1); }

struct Accumulator {
  double sum = 0;
  std::size_t count = 0;
  double light[kBands] = {}, view[kBands] = {};
  std::size_t lightCount[kBands] = {}, viewCount[kBands] = {};
};

std::vector<ElevationBand> bands(const double* sums, const std::size_t* counts, double alpha) {
  std::vector<ElevationBand> out;
  for (int b = 0; b < kBands; ++b) {
    if (!counts[b]) continue;
    out.push_back({b * kBandDeg, (b + 1) * kBandDeg, std::sqrt(sums[b] / counts[b]) / alpha, counts[b]});
  }
  return out;
}

}  // namespace

std::vector<FitError> measureFitErrors(const GltfMaterial& m, const std::vector<Direction>& lights,
                                       const std::vector<Direction>& views, const std::vector<Reference>& references,
                                       double alpha, bool progress) {
  if (!(alpha > 0)) throw Error("the fit's error needs a positive alpha (the material's maximum value)");
  const std::size_t texels = m.texels.size();
  std::vector<Accumulator> acc(references.size());
  std::vector<float> model(texels * 3), reference(texels * 3);
  Progress bar("glTF fit: measuring", lights.size() * views.size(), progress);
  for (std::size_t v = 0; v < views.size(); ++v) {
    const auto vu = views[v].unitVector();
    const Vec3 view{vu[0], vu[1], vu[2]};
    const int viewBand = bandOf(views[v].thetaDeg);
    for (std::size_t l = 0; l < lights.size(); ++l) {
      const auto lu = lights[l].unitVector();
      const Vec3 light{lu[0], lu[1], lu[2]};
      parallelFor(
          texels,
          [&](std::size_t begin, std::size_t end) {
            for (std::size_t t = begin; t < end; ++t) {
              const Vec3 value = m.value(static_cast<int>(t), light, view);
              for (int c = 0; c < 3; ++c) model[3 * t + c] = static_cast<float>(value[c]);
            }
          },
          1024);
      const int image = static_cast<int>(l * views.size() + v), lightBand = bandOf(lights[l].thetaDeg);
      for (std::size_t r = 0; r < references.size(); ++r) {
        references[r].image(image, reference.data());
        double sum = 0;
        for (std::size_t i = 0; i < texels * 3; ++i) {
          const double d = double(model[i]) - reference[i];
          sum += d * d;
        }
        if (!std::isfinite(sum))
          throw Error(references[r].source + ": a non-finite value in image (light " + std::to_string(l) + ", view " +
                      std::to_string(v) + ")");
        Accumulator& a = acc[r];
        a.sum += sum, a.count += texels * 3;
        a.light[lightBand] += sum, a.lightCount[lightBand] += texels * 3;
        a.view[viewBand] += sum, a.viewCount[viewBand] += texels * 3;
      }
      bar.advance();
    }
  }
  bar.finish();
  std::vector<FitError> out;
  for (std::size_t r = 0; r < references.size(); ++r) {
    const Accumulator& a = acc[r];
    FitError e;
    e.name = references[r].name, e.source = references[r].source;
    e.rmse = a.count ? std::sqrt(a.sum / a.count) / alpha : 0;
    e.byLight = bands(a.light, a.lightCount, alpha);
    e.byView = bands(a.view, a.viewCount, alpha);
    out.push_back(e);
  }
  return out;
}

ImageSource groundTruthSource(const std::string& stackDir, const std::vector<Direction>& lights,
                              const std::vector<Direction>& views, const Crop& crop, int width, int height) {
  struct Cache {
    std::mutex mutex;
    int view = -1;
    ImageF file;
  };
  auto cache = std::make_shared<Cache>();
  return [=](int image, float* rgb) {
    const int nv = static_cast<int>(views.size()), nl = static_cast<int>(lights.size());
    const int view = image % nv, light = image / nv;
    std::lock_guard<std::mutex> lock(cache->mutex);
    const std::string path = groundTruthPath(stackDir, views[view]);
    if (cache->view != view) {
      cache->file = readExr(path);
      cache->view = view;
      if (cache->file.height % nl != 0)
        throw fileError(path, "is " + std::to_string(cache->file.height) + " rows high, not a multiple of the " +
                                  std::to_string(nl) + " lights");
    }
    const ImageF& f = cache->file;
    const int blockHeight = f.height / nl;
    const int x0 = crop.width > 0 ? crop.x : 0, y0 = crop.width > 0 ? crop.y : 0;
    if (x0 + width > f.width || y0 + height > blockHeight)
      throw fileError(path, "is smaller than the stack's images (" + std::to_string(f.width) + " x " +
                                std::to_string(blockHeight) + " per light)");
    for (int y = 0; y < height; ++y) {
      const float* row = f.rgb.data() + (static_cast<std::size_t>(light) * blockHeight + y0 + y) * f.width * 3 + x0 * 3;
      std::copy(row, row + width * 3, rgb + static_cast<std::size_t>(y) * width * 3);
    }
  };
}

}  // namespace nbtf::gltf
