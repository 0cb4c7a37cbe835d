#include "eval/evaluate.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <set>

#include "cluster/cluster_values.h"
#include "eval/figures.h"
#include "io/ground_truth.h"
#include "util/error.h"
#include "util/parallel.h"
#include "util/progress.h"
#include "util/timer.h"

namespace nbtf {
namespace {

std::string imageName(const EvalResult& r, int image) {
  int nv = static_cast<int>(r.views.size());
  return "image " + std::to_string(image) + " (light " + formatDirection(r.lights[image / nv]) + ", view " +
         formatDirection(r.views[image % nv]) + ")";
}

}  // namespace

std::vector<DirectionPair> paperFigure7Pairs() {
  return {
      {"Fig. 7, top row", {15, 60}, {30, 60}, "The paper's first direction pair"},
      {"Fig. 7, bottom row (grazing)", {75, 345}, {75, 0},
       "The paper's grazing pair; the paper prints the light as (345\xC2\xB0, 0\xC2\xB0), which is not a valid "
       "direction, so (75\xC2\xB0, 0\xC2\xB0) is used"},
  };
}

namespace {

// Per-texel sums over images for the mean brightness maps, in fixed point (2^-32 of alpha):
// integer sums do not depend on the order the workers add them in. One set per worker.
constexpr double kFixed = 4294967296.0;
struct MeanSums {
  std::vector<std::vector<std::int64_t>> reference, reconstruction;
};

// Per-image errors against the float ground truth: the reconstruction's and the stored
// reference's.
struct GroundTruthTables {
  ErrorTable reconstruction, reference;
};

// The result's description of the material and the method, and alpha (the reference's
// maximum unless given).
// What the reference's values went through on their way to disk, and so what its distance
// from the float ground truth is made of. The UBO2003 layout is JPEG (FORMATS.md); 8-bit
// images in the other layouts are taken as lossless (UTIA's PNG).
void describeEncoding(const BtfStack& ref, EvalResult& r) {
  if (ref.sampleType() != SampleType::Srgb8) {
    r.referenceEncoding = "half float";
    r.noiseFloorCause = "half-precision rounding";
  } else if (ref.layout == Layout::Ubo2003) {
    r.referenceEncoding = "8-bit sRGB JPEG";
    r.noiseFloorCause = "mostly the JPEG's loss, then the 8-bit steps";
  } else {
    r.referenceEncoding = "8-bit sRGB";
    r.noiseFloorCause = "the 8-bit steps (and the images' compression, if lossy)";
  }
}

EvalResult describe(const EvalInputs& in, const EvalOptions& options) {
  const BtfStack& ref = *in.reference;
  EvalResult r;
  r.method = in.method, r.referenceName = in.referenceName, r.compressedName = in.compressedName;
  r.methodFamily = in.methodFamily.empty() ? in.method : in.methodFamily;
  r.methodParameter = in.methodParameter;
  r.details = in.details;
  r.width = ref.width(), r.height = ref.height();
  r.lights = ref.lights(), r.views = ref.views();
  r.sizes = in.sizes;
  describeEncoding(ref, r);
  r.blurOptions = options.blur;
  checkHoldoutImages(in.holdoutImages, ref.numImages());
  r.holdoutImages = in.holdoutImages;
  std::sort(r.holdoutImages.begin(), r.holdoutImages.end());
  r.alpha = in.alpha;
  if (!(r.alpha > 0)) {
    float lo, hi;
    ref.valueRange(lo, hi);
    if (!(hi > 0)) throw Error("evaluation: the reference is black everywhere; alpha (its maximum) would be 0");
    r.alpha = hi, r.alphaFromReference = true;
  }
  if (!std::isfinite(r.alpha)) throw Error("evaluation: alpha is not finite");
  return r;
}

// The compared pairs (nearest measured directions) into r.comparisons, and the blur sample:
// lights evenly spaced, views along a golden-ratio sequence, so the sample spreads over the
// (light, view) square instead of a diagonal (a stride through image indices lands on
// light == view for 81 x 81).
std::set<int> chooseImages(const BtfStack& ref, const EvalOptions& options, EvalResult& r) {
  for (const auto& pair : options.pairs) {
    Comparison c;
    c.name = pair.name, c.note = pair.note, c.requested = pair;
    c.light = nearestDirection(r.lights, pair.light);
    c.view = nearestDirection(r.views, pair.view);
    c.image = ref.imageIndex(c.light, c.view);
    c.exact = sameDirection(r.lights[c.light], pair.light) && sameDirection(r.views[c.view], pair.view);
    r.comparisons.push_back(c);
  }
  const int samples = std::min(options.blurSampleImages, ref.numImages());
  const int nl = ref.numLights(), nv = ref.numViews();
  std::set<int> blurImages;
  for (int i = 0; i < samples; ++i) {
    int light = static_cast<int>((i + 0.5) * nl / samples);
    double frac = std::fmod(0.5 + i * 0.6180339887498949, 1.0);
    blurImages.insert(ref.imageIndex(std::min(light, nl - 1), std::min(static_cast<int>(frac * nv), nv - 1)));
  }
  return blurImages;
}

// The pass: every image once, its errors into r.table, the mean sums, and the
// reconstructions of the images in `kept` (whose slots exist before the threads run).
MeanSums comparePass(const EvalInputs& in, const EvalOptions& options, EvalResult& r,
                     std::map<int, std::vector<float>>& kept, GroundTruthTables& truth) {
  const BtfStack& ref = *in.reference;
  const int numImages = ref.numImages();
  const std::size_t n = static_cast<std::size_t>(ref.numTexels()) * 3;
  r.table = ErrorTable(r.lights, r.views);
  const int workers = threadCount();
  std::vector<std::vector<float>> refBuf(workers), recBuf(workers), truthBuf(workers);
  if (in.groundTruth) truth = {ErrorTable(r.lights, r.views), ErrorTable(r.lights, r.views)};
  MeanSums sums{std::vector<std::vector<std::int64_t>>(workers), std::vector<std::vector<std::int64_t>>(workers)};
  Progress progress("eval: reconstruct + compare", static_cast<std::size_t>(numImages), options.progress);
  parallelForDynamic(static_cast<std::size_t>(numImages), [&](std::size_t index, int worker) {
    int image = static_cast<int>(index);
    auto& rb = refBuf[worker];
    auto& cb = recBuf[worker];
    rb.resize(n), cb.assign(n, std::numeric_limits<float>::quiet_NaN());  // unwritten values fail the check
    try {
      ref.imageLinear(image, rb.data());
      in.reconstruct(image, cb.data());
      r.table.set(image, errorSums(rb.data(), cb.data(), n, r.alpha));
      if (in.groundTruth) {
        auto& tb = truthBuf[worker];
        tb.assign(n, std::numeric_limits<float>::quiet_NaN());
        in.groundTruth(image, tb.data());
        truth.reconstruction.set(image, errorSums(tb.data(), cb.data(), n, r.alpha));
        truth.reference.set(image, errorSums(tb.data(), rb.data(), n, r.alpha));
      }
      auto& rs = sums.reference[worker];
      auto& cs = sums.reconstruction[worker];
      if (rs.empty()) rs.assign(n, 0), cs.assign(n, 0);
      const double scale = kFixed / r.alpha;
      for (std::size_t j = 0; j < n; ++j) {
        rs[j] += std::llround(rb[j] * scale);
        cs[j] += std::llround(cb[j] * scale);
      }
    } catch (const std::exception& e) {
      throw Error(imageName(r, image) + ": " + e.what());
    }
    auto it = kept.find(image);
    if (it != kept.end()) it->second = cb;
    progress.advance();
  });
  progress.finish();
  return sums;
}

// Mean brightness maps (linear, on the reference's scale), their RMSE / alpha and figure.
void meanBrightnessMaps(const MeanSums& sums, int numImages, EvalResult& r) {
  const std::size_t n = static_cast<std::size_t>(r.width) * r.height * 3;
  std::vector<float> refMean(n, 0.0f), recMean(n, 0.0f);
  const double toLinear = r.alpha / (kFixed * numImages);
  double sse = 0, brightest = 0;
  for (std::size_t j = 0; j < n; ++j) {
    std::int64_t a = 0, b = 0;
    for (std::size_t w = 0; w < sums.reference.size(); ++w)
      if (!sums.reference[w].empty()) a += sums.reference[w][j], b += sums.reconstruction[w][j];
    refMean[j] = static_cast<float>(a * toLinear);
    recMean[j] = static_cast<float>(b * toLinear);
    const double d = (static_cast<double>(b) - static_cast<double>(a)) / (kFixed * numImages);
    sse += d * d;
    brightest = std::max(brightest, static_cast<double>(refMean[j]));
  }
  r.meanMapRmse = std::sqrt(sse / static_cast<double>(n));
  // Brighten both maps alike for display; alpha scales with them so the error panel's units stay.
  r.meanMapGain = brightest > 0 ? r.alpha / brightest : 1.0;
  for (std::size_t j = 0; j < n; ++j) refMean[j] *= r.meanMapGain, recMean[j] *= r.meanMapGain;
  const float shownAlpha = static_cast<float>(r.alpha * r.meanMapGain);
  r.meanMapMagnification = chooseErrorMagnification(refMean.data(), recMean.data(), r.width * r.height, shownAlpha);
  char title[96];
  std::snprintf(title, sizeof title, "Mean brightness over all images (shown x %.3g)", r.meanMapGain);
  r.meanMapFigure = renderComparison(refMean.data(), recMean.data(), r.width, r.height, shownAlpha,
                                     r.meanMapMagnification, title);
}

// The cluster-mean floor of this reference, with and without the per-texel factors, and
// the cluster map (by split generation when adaptive: where the latents went).
void clusterFloor(const EvalInputs& in, EvalResult& r) {
  const BtfStack& ref = *in.reference;
  std::vector<int> everyImage(ref.numImages());
  for (int i = 0; i < ref.numImages(); ++i) everyImage[i] = i;
  r.floorRmse = clusterValues(ref, r.alpha, in.clusterIds, in.clusters, nullptr, 1, false, false)
                    .floorRmse(everyImage, ref.numTexels());
  if (!in.texelCoefficients.empty())
    r.floorRmseModulated = clusterValues(ref, r.alpha, in.clusterIds, in.clusters, in.texelCoefficients.data(),
                                         in.coefficientTerms, false, false, in.coefficientChannels)
                               .floorRmse(everyImage, ref.numTexels());
  const bool adaptive = !in.clusterGenerations.empty();
  r.clusterMapFigure = renderClusterMap(in.clusterIds, r.width, r.height, in.clusters, in.clusterGenerations,
                                        adaptive ? "Clusters by split generation (adaptive, k = " +
                                                       std::to_string(in.clusters) + ")"
                                                 : "Clusters (k = " + std::to_string(in.clusters) + ")");
  for (int c = 0; c < in.clusters; ++c) {
    const int g = adaptive ? std::max(0, in.clusterGenerations[c]) : 0;
    if (static_cast<int>(r.clustersPerGeneration.size()) <= g) r.clustersPerGeneration.resize(g + 1, 0);
    ++r.clustersPerGeneration[g];
  }
}

// The worst pair joins the comparisons, its reconstruction kept.
void addWorstComparison(const EvalInputs& in, EvalResult& r, std::map<int, std::vector<float>>& kept) {
  const int nv = static_cast<int>(r.views.size());
  Comparison worst;
  worst.name = "worst error";
  worst.note = "The (light, view) pair with the largest RMSE";
  worst.image = r.worstImage, worst.light = r.worstImage / nv, worst.view = r.worstImage % nv;
  worst.requested = {worst.name, r.views[worst.view], r.lights[worst.light], worst.note};
  r.comparisons.push_back(worst);
  if (kept.count(r.worstImage)) return;
  auto& buf = kept[r.worstImage];
  buf.assign(static_cast<std::size_t>(r.width) * r.height * 3, std::numeric_limits<float>::quiet_NaN());
  try {
    in.reconstruct(r.worstImage, buf.data());
  } catch (const std::exception& e) {
    throw Error(imageName(r, r.worstImage) + ": " + e.what());
  }
}

// Effective blur on every kept image (in parallel; each estimate is independent) and its median.
void estimateBlurs(const BtfStack& ref, const EvalOptions& options, const std::set<int>& images,
                   const std::map<int, std::vector<float>>& kept, EvalResult& r) {
  const int nv = ref.numViews();
  const std::size_t n = static_cast<std::size_t>(ref.numTexels()) * 3;
  std::vector<int> blurList(images.begin(), images.end());
  r.blurSamples.resize(blurList.size());
  Progress blurProgress("eval: effective blur", blurList.size(), options.progress);
  parallelForDynamic(blurList.size(), [&](std::size_t k, int) {
    int image = blurList[k];
    std::vector<float> reference(n);
    ref.imageLinear(image, reference.data());
    BlurSample& s = r.blurSamples[k];
    s.image = image, s.light = image / nv, s.view = image % nv;
    s.estimate = estimateBlur(reference.data(), kept.at(image).data(), r.width, r.height, r.alpha, options.blur);
    blurProgress.advance();
  });
  blurProgress.finish();
  std::vector<double> sigmas;
  for (const auto& s : r.blurSamples) sigmas.push_back(s.estimate.sigma);
  std::sort(sigmas.begin(), sigmas.end());
  std::size_t m = sigmas.size();
  r.blurSigmaMedian = m % 2 ? sigmas[m / 2] : 0.5 * (sigmas[m / 2 - 1] + sigmas[m / 2]);
}

// Comparison strips: reference | reconstruction | magnified error, per compared pair.
void comparisonStrips(const BtfStack& ref, const std::map<int, std::vector<float>>& kept, EvalResult& r) {
  std::vector<float> reference(static_cast<std::size_t>(ref.numTexels()) * 3);
  for (auto& c : r.comparisons) {
    c.error = r.table.image(c.image);
    for (const auto& s : r.blurSamples)
      if (s.image == c.image) c.blur = s.estimate;
    ref.imageLinear(c.image, reference.data());
    const auto& rec = kept.at(c.image);
    c.magnification = chooseErrorMagnification(reference.data(), rec.data(), ref.numTexels(), r.alpha);
    std::string title = c.name + ": light " + formatDirection(r.lights[c.light]) + ", view " +
                        formatDirection(r.views[c.view]);
    c.figure = renderComparison(reference.data(), rec.data(), r.width, r.height, r.alpha, c.magnification, title);
  }
}

}  // namespace

std::function<void(int image, float* linearRgb)> groundTruthBeside(const std::string& stackDir,
                                                                   const BtfStack& reference, const Crop& crop) {
  if (!hasGroundTruth(stackDir, reference.views())) return {};
  const std::vector<Direction> lights = reference.lights(), views = reference.views();
  const std::size_t values = static_cast<std::size_t>(reference.numTexels()) * 3;
  return [stackDir, lights, views, crop, values](int image, float* out) {
    const std::vector<float> rgb = readGroundTruthImage(stackDir, lights, views, image, crop);
    if (rgb.size() != values)
      throw fileError(groundTruthPath(stackDir, views[image % views.size()]),
                      "holds " + std::to_string(rgb.size() / 3) + " texels per image, the reference " +
                          std::to_string(values / 3));
    std::copy(rgb.begin(), rgb.end(), out);
  };
}

EvalResult evaluate(const EvalInputs& in, const EvalOptions& options) {
  auto start = std::chrono::steady_clock::now();
  if (!in.reference) throw Error("evaluation: no reference stack");
  if (!in.reconstruct) throw Error("evaluation: no reconstruction");
  const BtfStack& ref = *in.reference;
  if (ref.numImages() == 0 || ref.numTexels() == 0) throw Error("evaluation: the reference stack is empty");

  EvalResult r = describe(in, options);
  std::set<int> blurImages = chooseImages(ref, options, r);
  std::map<int, std::vector<float>> kept;  // image -> reconstruction
  for (const auto& c : r.comparisons) kept[c.image];
  for (int i : blurImages) kept[i];
  GroundTruthTables truth;
  const MeanSums sums = comparePass(in, options, r, kept, truth);
  meanBrightnessMaps(sums, ref.numImages(), r);
  if (in.clusters > 0) clusterFloor(in, r);

  r.all = r.table.all();
  r.training = r.hasHoldout() ? r.table.subset(r.holdoutImages, true) : r.all;
  if (r.hasHoldout()) r.holdout = r.table.subset(r.holdoutImages, false);
  r.byLightElevation = r.table.byLightElevation();
  r.byViewElevation = r.table.byViewElevation();
  r.worstImage = r.table.worstImage();
  if (in.groundTruth) {
    r.hasGroundTruth = true;
    r.groundTruthName = in.groundTruthName;
    r.groundTruthAll = truth.reconstruction.all();
    r.groundTruthTraining = r.hasHoldout() ? truth.reconstruction.subset(r.holdoutImages, true) : r.groundTruthAll;
    if (r.hasHoldout()) r.groundTruthHoldout = truth.reconstruction.subset(r.holdoutImages, false);
    r.referenceVsGroundTruth = truth.reference.all();
    if (r.hasHoldout()) r.referenceVsGroundTruthHoldout = truth.reference.subset(r.holdoutImages, false);
  }
  addWorstComparison(in, r, kept);
  blurImages.insert(r.worstImage);
  for (const auto& c : r.comparisons) blurImages.insert(c.image);
  estimateBlurs(ref, options, blurImages, kept, r);
  comparisonStrips(ref, kept, r);
  r.seconds = secondsSince(start);
  return r;
}

}  // namespace nbtf
