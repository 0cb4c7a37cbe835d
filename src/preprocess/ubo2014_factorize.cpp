#include "preprocess/ubo2014_factorize.h"

#include <Eigen/Core>
#include <Eigen/LU>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <memory>
#include <random>

#include "util/error.h"
#include "util/half.h"
#include "util/memory.h"
#include "util/parallel.h"
#include "util/progress.h"
#include "util/timer.h"

namespace nbtf {

namespace {

using MatrixF = Eigen::MatrixXf;
using Channels = std::array<MatrixF, 3>;

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

// The file's colour model applied to one linear RGB value, and undone.
class Decorrelation {
 public:
  explicit Decorrelation(std::int32_t model) : model_(model), toYuv_(yuvFromRgb()), toRgb_(toYuv_.inverse()) {}

  void forward(const float* rgb, float* out) const {
    if (model_ == 0) {
      for (int c = 0; c < 3; ++c) out[c] = rgb[c];
      return;
    }
    Eigen::Vector3d v = toYuv_ * Eigen::Vector3d(std::max(0.0f, rgb[0]), std::max(0.0f, rgb[1]), std::max(0.0f, rgb[2]));
    const double y = std::max(0.0, v[0]) + kUboDrrEps;
    out[0] = static_cast<float>(std::log(y));
    out[1] = static_cast<float>(v[1] / y);
    out[2] = static_cast<float>(v[2] / y);
  }
  // The input forward() was given, as far as its clamping keeps it.
  Eigen::Vector3d backward(float c0, float c1, float c2) const {
    if (model_ == 0) return Eigen::Vector3d(c0, c1, c2);
    const double y = std::exp(static_cast<double>(c0));
    return toRgb_ * Eigen::Vector3d(y - kUboDrrEps, c1 * y, c2 * y);
  }

 private:
  std::int32_t model_;
  Eigen::Matrix3d toYuv_, toRgb_;
};

// Rows of at most `bytes` at a time, but at least two images per thread.
int blockRows(int texels, int rows, std::size_t bytes) {
  const std::size_t bytesPerRow = static_cast<std::size_t>(texels) * 3 * sizeof(float);
  const std::size_t fit = std::max<std::size_t>(1, bytes / bytesPerRow);
  return static_cast<int>(std::min<std::size_t>(rows, std::max<std::size_t>(fit, 2 * threadCount())));
}

using RowBlock = std::array<Eigen::Ref<const MatrixF>, 3>;

// The three decorrelated channel matrices A_c: one row per light/view pair in the file's
// order (light fastest), one column per texel. The SVD sees them only through products and
// passes over blocks of rows, so that they can be held in memory or made again for each pass.
class ChannelMatrices {
 public:
  ChannelMatrices(int lights, int views, int texels, std::size_t blockBytes)
      : lights_(lights), views_(views), texels_(texels), blockBytes_(blockBytes) {}
  virtual ~ChannelMatrices() = default;
  int rows() const { return lights_ * views_; }
  int texels() const { return texels_; }
  // The caller's image of a row (image = light * views + view).
  int imageOfRow(int row) const { return (row % lights_) * views_ + row / lights_; }
  int rowsPerBlock() const { return blockRows(texels_, rows(), blockBytes_); }

  // visit(firstRow, rows of each channel) for consecutive blocks of rows, in order, on the caller's thread.
  virtual void forEachBlock(const std::function<void(int, const RowBlock&)>& visit) = 0;

  // A_c m_c for each channel (rows x columns of m_c).
  virtual Channels times(const Channels& m) {
    Channels y;
    for (int c = 0; c < 3; ++c) y[c].resize(rows(), m[c].cols());
    forEachBlock([&](int first, const RowBlock& block) {
      const int n = static_cast<int>(block[0].rows());
      parallelFor(n, [&](std::size_t begin, std::size_t end) {  // each task owns its rows of y
        const int r = static_cast<int>(begin), count = static_cast<int>(end - begin);
        for (int c = 0; c < 3; ++c) y[c].middleRows(first + r, count).noalias() = block[c].middleRows(r, count) * m[c];
      });
    });
    return y;
  }
  // A_c^T q_c for each channel (texels x columns of q_c).
  virtual Channels transposeTimes(const Channels& q) {
    Channels z;
    for (int c = 0; c < 3; ++c) z[c] = MatrixF::Zero(texels(), q[c].cols());
    constexpr int kSlice = 1024;  // texels per task: each task owns its rows of z (no race, a fixed sum order)
    const std::size_t slices = (texels() + kSlice - 1) / kSlice;
    forEachBlock([&](int first, const RowBlock& block) {
      const int n = static_cast<int>(block[0].rows());
      parallelFor(3 * slices, [&](std::size_t begin, std::size_t end) {
        for (std::size_t j = begin; j < end; ++j) {
          const int c = static_cast<int>(j / slices);
          const int t0 = static_cast<int>(j % slices) * kSlice, count = std::min(kSlice, texels() - t0);
          z[c].middleRows(t0, count).noalias() +=
              block[c].middleCols(t0, count).transpose() * q[c].middleRows(first, n);
        }
      });
    });
    return z;
  }

 private:
  int lights_, views_, texels_;
  std::size_t blockBytes_;
};

// Renders the rows block by block, in order, each image(i, rgb) decorrelated:
// visit(first row, the block's rows).
void renderBlocks(const ChannelMatrices& a, const std::function<void(int, float*)>& image, const Decorrelation& colour,
                  const std::function<void(int, const RowBlock&)>& visit) {
  const int step = a.rowsPerBlock(), texels = a.texels();
  Channels block;
  for (int first = 0; first < a.rows(); first += step) {
    const int n = std::min(step, a.rows() - first);
    for (MatrixF& m : block) m.resize(n, texels);
    parallelForDynamic(n, [&](std::size_t r, int) {
      std::vector<float> rgb(static_cast<std::size_t>(texels) * 3);
      image(a.imageOfRow(first + static_cast<int>(r)), rgb.data());
      float v[3];
      for (int t = 0; t < texels; ++t) {
        colour.forward(rgb.data() + static_cast<std::size_t>(t) * 3, v);
        for (int c = 0; c < 3; ++c) block[c](static_cast<Eigen::Index>(r), t) = v[c];
      }
    });
    visit(first, RowBlock{block[0], block[1], block[2]});
  }
}

// Made once and held: products are whole-matrix products.
class HeldMatrices : public ChannelMatrices {
 public:
  HeldMatrices(int lights, int views, int texels, const std::function<void(int, float*)>& image,
               const Decorrelation& colour, std::size_t blockBytes, bool progress)
      : ChannelMatrices(lights, views, texels, blockBytes) {
    for (MatrixF& m : a_) m.resize(rows(), texels);
    Progress bar("images", rows(), progress);
    renderBlocks(*this, image, colour, [&](int first, const RowBlock& block) {
      for (int c = 0; c < 3; ++c) a_[c].middleRows(first, block[c].rows()) = block[c];
      bar.advance(static_cast<std::size_t>(block[0].rows()));
    });
    bar.finish();
  }
  void forEachBlock(const std::function<void(int, const RowBlock&)>& visit) override {
    const int step = rowsPerBlock();
    for (int first = 0; first < rows(); first += step) {
      const int n = std::min(step, rows() - first);
      visit(first, RowBlock{a_[0].middleRows(first, n), a_[1].middleRows(first, n), a_[2].middleRows(first, n)});
    }
  }
  Channels times(const Channels& m) override {
    Channels y;
    for (int c = 0; c < 3; ++c) y[c] = a_[c] * m[c];
    return y;
  }
  Channels transposeTimes(const Channels& q) override {
    Channels z;
    for (int c = 0; c < 3; ++c) z[c] = a_[c].transpose() * q[c];
    return z;
  }

 private:
  Channels a_;
};

// Never held: every pass asks for the images again, a block of rows at a time.
class StreamedMatrices : public ChannelMatrices {
 public:
  StreamedMatrices(int lights, int views, int texels, const std::function<void(int, float*)>& image,
                   const Decorrelation& colour, std::size_t blockBytes, int passes, bool progress)
      : ChannelMatrices(lights, views, texels, blockBytes),
        image_(image),
        colour_(colour),
        bar_("images, " + std::to_string(passes) + " passes", static_cast<std::size_t>(passes) * rows(), progress) {}
  void forEachBlock(const std::function<void(int, const RowBlock&)>& visit) override {
    renderBlocks(*this, image_, colour_, [&](int first, const RowBlock& block) {
      visit(first, block);
      bar_.advance(static_cast<std::size_t>(block[0].rows()));
    });
    ++passes_;
  }
  int passes() const { return passes_; }

 private:
  const std::function<void(int, float*)>& image_;
  const Decorrelation& colour_;
  Progress bar_;
  int passes_ = 0;
};

// The stored factors against the input, image by image.
void measure(ChannelMatrices& a, const Ubo2014Btf& btf, const Decorrelation& colour, Ubo2014FactorizeReport& report) {
  double sum = 0, sumIn = 0, maxErr = 0;
  const int texels = a.texels();
  a.forEachBlock([&](int first, const RowBlock& block) {
    const int n = static_cast<int>(block[0].rows());
    std::vector<std::array<double, 3>> partial(n);  // per row: squared error, input sum, max error
    parallelForDynamic(n, [&](std::size_t r, int) {
      std::vector<float> decoded(static_cast<std::size_t>(texels) * 3);
      btf.imageLinear(a.imageOfRow(first + static_cast<int>(r)), decoded.data());
      std::array<double, 3> s{0, 0, 0};
      const Eigen::Index row = static_cast<Eigen::Index>(r);
      for (int t = 0; t < texels; ++t) {
        const Eigen::Vector3d in = colour.backward(block[0](row, t), block[1](row, t), block[2](row, t));
        for (int c = 0; c < 3; ++c) {
          const double d = decoded[static_cast<std::size_t>(t) * 3 + c] - in[c];
          s[0] += d * d, s[1] += in[c], s[2] = std::max(s[2], std::abs(d));
        }
      }
      partial[r] = s;
    });
    for (const auto& s : partial) sum += s[0], sumIn += s[1], maxErr = std::max(maxErr, s[2]);
  });
  const double n = 3.0 * a.rows() * texels;
  report.rmseLinear = std::sqrt(sum / n);
  report.maxAbsError = maxErr;
  report.inputMean = sumIn / n;
}

}  // namespace

void checkUbo2014FactorizeOptions(const Ubo2014FactorizeOptions& o) {
  if (o.colorModel != 0 && o.colorModel != 11)
    throw Error("UBO2014 writer: colour model " + std::to_string(o.colorModel) + " (" + uboColorModelName(o.colorModel) +
                ") cannot be written; nbtf writes 11 (Ylog U/Y V/Y) or 0 (RGB)");
  if (o.components < 1) throw Error("UBO2014 writer: --components must be at least 1");
  if (o.scalarSize != 2 && o.scalarSize != 4) throw Error("UBO2014 writer: scalar size must be 2 (half) or 4 (float)");
  if (o.powerIterations < 0 || o.powerIterations > 10)
    throw Error("UBO2014 writer: --power-iterations must be 0 to 10, got " + std::to_string(o.powerIterations));
}

std::size_t ubo2014MatrixBytes(int images, int texels) {
  return static_cast<std::size_t>(images) * static_cast<std::size_t>(texels) * 3 * sizeof(float);
}

Ubo2014Btf factorizeUbo2014(const std::vector<Direction>& lights, const std::vector<Direction>& views, int width,
                            int height, const std::function<void(int, float*)>& image,
                            const Ubo2014FactorizeOptions& o, Ubo2014FactorizeReport* report) {
  const auto start = std::chrono::steady_clock::now();
  checkUbo2014FactorizeOptions(o);
  const int nl = static_cast<int>(lights.size()), nv = static_cast<int>(views.size());
  const int pairs = nl * nv, texels = width * height;
  if (pairs == 0 || texels == 0) throw Error("UBO2014 writer: nothing to write (no images or no texels)");

  const Decorrelation colour(o.colorModel);
  const std::size_t limit = o.memoryLimit ? o.memoryLimit : defaultMemoryLimit() / 2;
  const bool streamed = ubo2014MatrixBytes(pairs, texels) > limit;
  const int powerIterations = o.powerIterations;
  std::unique_ptr<ChannelMatrices> a;
  if (streamed)
    a = std::make_unique<StreamedMatrices>(nl, nv, texels, image, colour, o.blockBytes,
                                           2 + 2 * powerIterations + (report ? 1 : 0), o.progress);
  else
    a = std::make_unique<HeldMatrices>(nl, nv, texels, image, colour, o.blockBytes, o.progress);

  // Randomized truncated SVD of each channel.
  const int k = std::min({o.components, pairs, texels});
  const int p = std::min({k + std::max(0, o.oversampling), pairs, texels});
  Channels omega;
  for (int c = 0; c < 3; ++c) {
    std::mt19937_64 rng(o.seed + 7919u * c);
    std::normal_distribution<float> normal(0.0f, 1.0f);
    omega[c].resize(texels, p);
    for (Eigen::Index i = 0; i < omega[c].size(); ++i) omega[c].data()[i] = normal(rng);
  }
  Channels y = a->times(omega);
  omega = Channels{};
  Channels q;
  for (int it = 0; it < powerIterations; ++it) {
    for (int c = 0; c < 3; ++c) q[c] = orthonormal(y[c]);
    Channels z = a->transposeTimes(q);
    for (int c = 0; c < 3; ++c) z[c] = orthonormal(z[c]);
    y = a->times(z);
  }
  for (int c = 0; c < 3; ++c) q[c] = orthonormal(y[c]);  // pairs x p
  const Channels bt = a->transposeTimes(q);              // texels x p: B^T, B = Q^T A

  std::vector<Ubo2014Channel> channels(3);
  Progress bar("factorize", 3, o.progress && !streamed);
  for (int c = 0; c < 3; ++c) {
    Eigen::BDCSVD<MatrixF> svd(bt[c], Eigen::ComputeThinU | Eigen::ComputeThinV);  // B^T = Vb Sb Ub^T
    Ubo2014Channel& ch = channels[c];
    ch.scalarSize = o.scalarSize;
    ch.components = k;
    ch.uRows = pairs, ch.sxvRows = texels;
    const MatrixF u = q[c] * svd.matrixV().leftCols(k);                                          // pairs x k
    const MatrixF sxv = svd.matrixU().leftCols(k) * svd.singularValues().head(k).asDiagonal();  // texels x k
    ch.s.assign(svd.singularValues().data(), svd.singularValues().data() + k);
    auto stored = [&](float f) { return o.scalarSize == 2 ? roundToHalf(f) : f; };
    ch.u.resize(static_cast<std::size_t>(pairs) * k);
    ch.sxv.resize(static_cast<std::size_t>(texels) * k);
    for (int r = 0; r < pairs; ++r)
      for (int j = 0; j < k; ++j) ch.u[static_cast<std::size_t>(r) * k + j] = stored(u(r, j));
    for (int t = 0; t < texels; ++t)
      for (int j = 0; j < k; ++j) ch.sxv[static_cast<std::size_t>(t) * k + j] = stored(sxv(t, j));
    // Decoding never reads the singular values (SxV holds them); a whole material's largest
    // can pass half's range (65504), and is then stored as the largest half, not infinity.
    constexpr float kLargestHalf = 65504.0f;
    for (float& s : ch.s) s = stored(o.scalarSize == 2 ? std::min(s, kLargestHalf) : s);
    for (const std::vector<float>* part : {&ch.u, &ch.sxv})
      for (float f : *part)
        if (!std::isfinite(f))
          throw Error("UBO2014 writer: channel " + std::to_string(c) + ": a factor is not finite (over the " +
                      (o.scalarSize == 2 ? std::string("half-float range, 65504") : std::string("float range")) + ")");
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
    measure(*a, btf, colour, *report);
    report->components = k;
    report->streamed = streamed;
    report->passes = streamed ? static_cast<const StreamedMatrices&>(*a).passes() : 1;
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
