#include "preprocess/ubo2014_factorize.h"

#include <Eigen/Core>
#include <Eigen/LU>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>

#include "util/error.h"
#include "util/half.h"
#include "util/parallel.h"
#include "util/progress.h"
#include "util/timer.h"

namespace nbtf {

namespace {

using MatrixF = Eigen::MatrixXf;

// Inverse of Bonn's YUV -> RGB matrix (undecorrelate.m), so that decoding gives back the input.
Eigen::Matrix3d yuvFromRgb() {
  Eigen::Matrix3d rgbFromYuv;
  rgbFromYuv << 1, 0, 1.13983, 1, -0.39465, -0.5806, 1, 2.03211, 0;
  return rgbFromYuv.inverse();
}

MatrixF orthonormal(const MatrixF& y) {
  Eigen::HouseholderQR<MatrixF> qr(y);
  return qr.householderQ() * MatrixF::Identity(y.rows(), y.cols());
}

}  // namespace

void checkUbo2014FactorizeOptions(const Ubo2014FactorizeOptions& o) {
  if (o.colorModel != 0 && o.colorModel != 11)
    throw Error("UBO2014 writer: colour model " + std::to_string(o.colorModel) + " (" + uboColorModelName(o.colorModel) +
                ") cannot be written; nbtf writes 11 (Ylog U/Y V/Y) or 0 (RGB)");
  if (o.components < 1) throw Error("UBO2014 writer: --components must be at least 1");
  if (o.scalarSize != 2 && o.scalarSize != 4) throw Error("UBO2014 writer: scalar size must be 2 (half) or 4 (float)");
}

Ubo2014Btf factorizeUbo2014(const std::vector<Direction>& lights, const std::vector<Direction>& views, int width,
                            int height, const std::function<void(int, float*)>& image,
                            const Ubo2014FactorizeOptions& o, Ubo2014FactorizeReport* report) {
  const auto start = std::chrono::steady_clock::now();
  checkUbo2014FactorizeOptions(o);
  const int nl = static_cast<int>(lights.size()), nv = static_cast<int>(views.size());
  const int pairs = nl * nv, texels = width * height;
  if (pairs == 0 || texels == 0) throw Error("UBO2014 writer: nothing to write (no images or no texels)");

  // The decorrelated channel matrices, rows in the file's order (light fastest).
  std::vector<MatrixF> a(3, MatrixF(pairs, texels));
  const Eigen::Matrix3d toYuv = yuvFromRgb();
  const double eps = kUboDrrEps;
  {
    Progress bar("images", pairs, o.progress);
    parallelForDynamic(pairs, [&](std::size_t i, int) {
      std::vector<float> rgb(static_cast<std::size_t>(texels) * 3);
      image(static_cast<int>(i), rgb.data());
      const int row = static_cast<int>(i / nv) + nl * static_cast<int>(i % nv);
      for (int t = 0; t < texels; ++t) {
        const float* p = rgb.data() + static_cast<std::size_t>(t) * 3;
        if (o.colorModel == 0) {
          for (int c = 0; c < 3; ++c) a[c](row, t) = p[c];
          continue;
        }
        Eigen::Vector3d v = toYuv * Eigen::Vector3d(std::max(0.0f, p[0]), std::max(0.0f, p[1]), std::max(0.0f, p[2]));
        const double y = std::max(0.0, v[0]) + eps;
        a[0](row, t) = static_cast<float>(std::log(y));
        a[1](row, t) = static_cast<float>(v[1] / y);
        a[2](row, t) = static_cast<float>(v[2] / y);
      }
      bar.advance();
    });
    bar.finish();
  }

  // Randomized truncated SVD per channel.
  const int k = std::min({o.components, pairs, texels});
  const int p = std::min({k + std::max(0, o.oversampling), pairs, texels});
  std::vector<Ubo2014Channel> channels(3);
  Progress bar("factorize", 3, o.progress);
  for (int c = 0; c < 3; ++c) {
    std::mt19937_64 rng(o.seed + 7919u * c);
    std::normal_distribution<float> normal(0.0f, 1.0f);
    MatrixF omega(texels, p);
    for (Eigen::Index i = 0; i < omega.size(); ++i) omega.data()[i] = normal(rng);
    MatrixF y = a[c] * omega;
    for (int it = 0; it < o.powerIterations; ++it) {
      MatrixF z = orthonormal(a[c].transpose() * orthonormal(y));
      y = a[c] * z;
    }
    const MatrixF q = orthonormal(y);                 // pairs x p
    const MatrixF bt = a[c].transpose() * q;          // texels x p: B^T, B = Q^T A
    Eigen::BDCSVD<MatrixF> svd(bt, Eigen::ComputeThinU | Eigen::ComputeThinV);  // B^T = Vb Sb Ub^T
    Ubo2014Channel& ch = channels[c];
    ch.scalarSize = o.scalarSize;
    ch.components = k;
    ch.uRows = pairs, ch.sxvRows = texels;
    const MatrixF u = q * svd.matrixV().leftCols(k);                                     // pairs x k
    const MatrixF sxv = svd.matrixU().leftCols(k) * svd.singularValues().head(k).asDiagonal();  // texels x k
    ch.s.assign(svd.singularValues().data(), svd.singularValues().data() + k);
    auto stored = [&](float f) { return o.scalarSize == 2 ? roundToHalf(f) : f; };
    ch.u.resize(static_cast<std::size_t>(pairs) * k);
    ch.sxv.resize(static_cast<std::size_t>(texels) * k);
    for (int r = 0; r < pairs; ++r)
      for (int j = 0; j < k; ++j) ch.u[static_cast<std::size_t>(r) * k + j] = stored(u(r, j));
    for (int t = 0; t < texels; ++t)
      for (int j = 0; j < k; ++j) ch.sxv[static_cast<std::size_t>(t) * k + j] = stored(sxv(t, j));
    for (float& s : ch.s) s = stored(s);
    bar.advance();
  }
  bar.finish();

  Ubo2014Meta meta;
  meta.measurementSetup = "nbtf";
  meta.lights = lights;
  meta.views = views;
  meta.width = width, meta.height = height;
  meta.colorModel = o.colorModel;
  meta.maxComponents = static_cast<std::uint32_t>(k);
  meta.xml = o.xml;
  Ubo2014Btf btf(std::move(meta), std::move(channels));

  if (report) {
    // Decode what is stored and compare with the input, recovered from the channel matrices.
    report->components = k;
    double sum = 0, sumIn = 0, maxErr = 0;
    const Eigen::Matrix3d toRgb = toYuv.inverse();
    constexpr int kBlock = 32;
    std::vector<float> rows(static_cast<std::size_t>(kBlock) * pairs * 3);
    std::vector<int> ids(kBlock);
    for (int first = 0; first < texels; first += kBlock) {
      const int count = std::min(kBlock, texels - first);
      for (int j = 0; j < count; ++j) ids[j] = first + j;
      btf.abrdfsLinear(ids.data(), count, rows.data());
      for (int j = 0; j < count; ++j)
        for (int i = 0; i < pairs; ++i) {
          const int row = i / nv + nl * (i % nv), t = first + j;
          Eigen::Vector3d in(a[0](row, t), a[1](row, t), a[2](row, t));
          if (o.colorModel == 11) {
            const double y = std::exp(in[0]);
            in = toRgb * Eigen::Vector3d(y - eps, in[1] * y, in[2] * y);
          }
          for (int c = 0; c < 3; ++c) {
            const double d = rows[(static_cast<std::size_t>(j) * pairs + i) * 3 + c] - in[c];
            sum += d * d, sumIn += in[c], maxErr = std::max(maxErr, std::abs(d));
          }
        }
    }
    const double n = 3.0 * pairs * texels;
    report->rmseLinear = std::sqrt(sum / n);
    report->maxAbsError = maxErr;
    report->inputMean = sumIn / n;
    report->seconds = secondsSince(start);
  }
  return btf;
}

Ubo2014Btf factorizeUbo2014(const BtfStack& stack, const Ubo2014FactorizeOptions& options,
                            Ubo2014FactorizeReport* report) {
  return factorizeUbo2014(
      stack.lights(), stack.views(), stack.width(), stack.height(),
      [&](int i, float* rgb) { stack.imageLinear(i, rgb); }, options, report);
}

}  // namespace nbtf
