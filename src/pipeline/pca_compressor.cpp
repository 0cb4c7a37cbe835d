#include "pipeline/pca_compressor.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <nlohmann/json.hpp>

#include "linalg/blas.h"
#include "cluster/pca.h"
#include "codec/decoder.h"
#include "codec/pca_model.h"
#include "pipeline/compress_parts.h"
#include "model/training_set.h"
#include "preprocess/abrdf_matrix.h"
#include "util/error.h"
#include "util/parallel.h"
#include "util/progress.h"
#include "util/timer.h"

namespace nbtf {
namespace {

using json = nlohmann::json;


// The neural methods' hold-out choice (model/training_set.cpp), reused rather than copied:
// a per-texel TrainingSet over the same stack, fraction and seed picks the same images.
std::vector<int> holdoutImagesFor(const BtfStack& stack, float alpha, const MatrixXfCol& x, double fraction,
                                  std::uint64_t seed) {
  if (!(fraction > 0)) return {};
  TrainInputs inputs;
  inputs.stack = &stack;
  inputs.alpha = alpha;
  inputs.encoderInputs = &x;  // per-texel mode: one row per texel (only its shape is used)
  TrainingSet set(inputs, fraction, seed, /*progress=*/false);
  return set.holdoutImages();
}

// Keeps the columns of the fitted images (3 per image, in image order) in place and drops
// the rest, without a second copy of the matrix.
void keepImageColumns(MatrixXfCol& x, const std::vector<int>& images) {
  const Eigen::Index rows = x.rows();
  for (std::size_t j = 0; j < images.size(); ++j)
    for (int c = 0; c < 3; ++c) {
      const Eigen::Index from = 3 * static_cast<Eigen::Index>(images[j]) + c, to = 3 * static_cast<Eigen::Index>(j) + c;
      if (from != to) std::copy(x.col(from).data(), x.col(from).data() + rows, x.col(to).data());
    }
  x.conservativeResize(rows, 3 * static_cast<Eigen::Index>(images.size()));
}

// Squared error sums per image of the decoded material against the stack (normalized).
std::vector<double> squaredErrorPerImage(const CompressedBtf& btf, const BtfStack& stack, float alpha, bool progress) {
  NbtfDecoder decoder(btf, DecoderOptions{}, "PCA result");
  const int images = stack.numImages(), nv = stack.numViews();
  const std::size_t values = static_cast<std::size_t>(stack.numTexels()) * 3;
  std::vector<double> sse(static_cast<std::size_t>(images), 0.0);
  const int workers = threadCount();
  std::vector<std::vector<float>> decoded(workers, std::vector<float>(values)), reference(workers, std::vector<float>(values));
  Progress bar("pca rmse", images, progress);
  parallelForDynamic(static_cast<std::size_t>(images), [&](std::size_t image, int worker) {
    const int i = static_cast<int>(image);
    decoder.decodeImage(stack.lights()[i / nv], stack.views()[i % nv], decoded[worker].data(), OutputScale::Normalized,
                        0, 0, false);
    stack.imageLinear(i, reference[worker].data());
    double s = 0;
    for (std::size_t k = 0; k < values; ++k) {
      const double d = static_cast<double>(decoded[worker][k]) - static_cast<double>(reference[worker][k] / alpha);
      s += d * d;
    }
    sse[image] = s;
    bar.advance();
  });
  bar.finish();
  return sse;
}

}  // namespace

int maxPcaComponents(std::int64_t texels, std::int64_t fittedImages) {
  return static_cast<int>(std::min<std::int64_t>({texels, 3 * fittedImages, 1 << 16}));
}

namespace {

// The material: every image gets a mean and basis row (held-out ones interpolated over the fitted
// ones), every texel its coefficients.
CompressedBtf assemblePca(const BtfStack& stack, float alpha, int components, const PcaResult& pca,
                          const MatrixXfCol& coefficients, const std::vector<int>& fittedImages,
                          const std::vector<int>& holdout, const std::vector<std::uint8_t>& fitted) {
  const int texels = stack.numTexels(), images = stack.numImages();
  CompressedBtf b = compressedFrame(stack, CodecMethod::Pca, alpha);
  b.latentDim = components;
  b.latentRows = texels;
  const std::size_t c = static_cast<std::size_t>(components);
  b.latents.resize(static_cast<std::size_t>(texels) * c);
  for (int t2 = 0; t2 < texels; ++t2)
    for (std::size_t k = 0; k < c; ++k) b.latents[t2 * c + k] = coefficients(t2, static_cast<Eigen::Index>(k));
  b.pcaMean.assign(3 * static_cast<std::size_t>(images), 0.0f);
  b.pcaBasis.assign(3 * static_cast<std::size_t>(images) * c, 0.0f);
  for (std::size_t j = 0; j < fittedImages.size(); ++j)
    for (int ch = 0; ch < 3; ++ch) {
      const std::size_t row = 3 * static_cast<std::size_t>(fittedImages[j]) + ch;
      const Eigen::Index fittedRow = 3 * static_cast<Eigen::Index>(j) + ch;
      b.pcaMean[row] = pca.mean[fittedRow];
      for (std::size_t k = 0; k < c; ++k) b.pcaBasis[row * c + k] = pca.basis(fittedRow, static_cast<Eigen::Index>(k));
    }
  if (!holdout.empty()) {
    DirectionInterpolator fittedOnly(stack.lights(), stack.views(), fitted);
    const int nv = stack.numViews();
    for (int h : holdout) {
      const std::size_t row = 3 * static_cast<std::size_t>(h);
      combinePcaRows(b.pcaMean.data(), b.pcaBasis.data(), components,
                     fittedOnly.weights(stack.lights()[h / nv], stack.views()[h % nv]), &b.pcaMean[row],
                     &b.pcaBasis[row * c]);
    }
  }
  b.holdoutImages = holdout;
  return b;
}

// Provenance: no timings or paths of this run, so the same seed gives the same bytes.
std::string pcaMetadataJson(const BtfStack& stack, const CompressOptions& o, const CompressStats& stats,
                            const PcaOptions& po, std::size_t fittedImages) {
  const int components = stats.pcaComponents;
  json meta;
  meta["method"] = "pca";
  meta["seed"] = o.train.seed;
  meta["threads"] = threadCount();
  meta["source"] = json::parse(sourceMetadataJson(stack));
  meta["pca"] = {{"components", components},
                 {"explained_variance_ratio", stats.pcaExplainedVarianceRatio},
                 {"fitted_images", fittedImages},
                 {"data", "linear RGB / alpha, mean-centred (no log transform or standardization)"},
                 {"oversampling", po.oversampling},
                 {"power_iterations", po.powerIterations},
                 {"interpolation", "modified Shepard weights over the " + std::to_string(kPcaNeighbours) +
                                       " nearest measured (light, view) pairs"}};
  meta["training"] = {{"rmse_train", stats.rmseTrain},
                      {"rmse_holdout", stats.rmseHoldout < 0 ? json(nullptr) : json(stats.rmseHoldout)},
                      {"rmse_space", "linear RGB / alpha (eq. 10)"},
                      {"holdout_fraction", o.train.holdoutFraction}};
  return meta.dump();
}

}  // namespace

CompressedBtf compressPcaStack(const BtfStack& stack, const CompressOptions& o, CompressStats& stats) {
  const int texels = stack.numTexels(), images = stack.numImages();
  const int components = o.pcaComponents;
  stats.method = CodecMethod::Pca;
  stats.texels = texels;
  stats.images = images;
  stats.clusters = 0;
  stats.pcaComponents = components;
  if (components < 1)
    throw Error("--components must be >= 1 for the PCA baseline, got " + std::to_string(components));

  // ---- Preprocess: linear ABRDF matrix / alpha (the neural methods' targets, eq. 5)
  auto t = Clock::now();
  const float alpha = targetAlpha(stack);
  stats.alpha = alpha;
  MatrixXfCol x = abrdfMatrix(stack, o.progress);
  x.array() /= alpha;
  const std::vector<int> holdout = holdoutImagesFor(stack, alpha, x, o.train.holdoutFraction, o.train.seed);
  std::vector<std::uint8_t> fitted(static_cast<std::size_t>(images), 1);
  for (int h : holdout) fitted[static_cast<std::size_t>(h)] = 0;
  std::vector<int> fittedImages;
  for (int i = 0; i < images; ++i)
    if (fitted[static_cast<std::size_t>(i)]) fittedImages.push_back(i);
  const int maxComponents = maxPcaComponents(texels, static_cast<std::int64_t>(fittedImages.size()));
  if (components > maxComponents)
    throw Error("--components " + std::to_string(components) + " is more than the PCA baseline allows here: at most " +
                std::to_string(maxComponents) + " = min(" + std::to_string(texels) + " texels, 3 x " +
                std::to_string(fittedImages.size()) + (holdout.empty() ? " images" : " fitted (not held-out) images") +
                ")");
  keepImageColumns(x, fittedImages);
  stats.seconds.preprocess = secondsSince(t);

  // ---- Fit: mean, basis and the coefficients that project each texel onto the basis
  t = Clock::now();
  PcaOptions po;
  po.components = components;
  po.seed = o.train.seed;
  po.progress = o.progress;
  PcaResult pca = randomizedPca(x, po);
  stats.pcaExplainedVarianceRatio = pca.explainedRatio();
  // Coefficients = (X - mean) basis, the least-squares optimum for the basis (the SVD's
  // scores miss whatever the randomized sketch did not capture).
  MatrixXfCol coefficients;
  blasMultiply(x, false, pca.basis, coefficients);
  {
    Eigen::RowVectorXf shift = pca.mean.transpose() * pca.basis;
    coefficients.rowwise() -= shift;
  }
  x.resize(0, 0);

  // ---- Assemble, then the RMSE of eq. (10) by decoding the result (the stored float32 values,
  // as eval does)
  CompressedBtf b = assemblePca(stack, alpha, components, pca, coefficients, fittedImages, holdout, fitted);
  b.storage.metadataZstd = o.train.storage.metadata == "zstd";
  b.storage.directionsZstd = o.train.storage.directions == "zstd";
  stats.holdoutImages = static_cast<int>(holdout.size());
  std::vector<double> sse = squaredErrorPerImage(b, stack, alpha, o.progress);
  double fitSse = 0, holdoutSse = 0;
  for (int i = 0; i < images; ++i) (fitted[i] ? fitSse : holdoutSse) += sse[static_cast<std::size_t>(i)];
  const double perImage = 3.0 * texels;
  stats.rmseTrain = std::sqrt(fitSse / (perImage * static_cast<double>(fittedImages.size())));
  stats.rmseHoldout = holdout.empty() ? -1 : std::sqrt(holdoutSse / (perImage * static_cast<double>(holdout.size())));
  b.metadataJson = pcaMetadataJson(stack, o, stats, po, fittedImages.size());
  b.validate("compressed result");
  stats.sizes = computeSizes(b);
  stats.seconds.pca = secondsSince(t);
  return b;
}

}  // namespace nbtf
