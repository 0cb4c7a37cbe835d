#include "preprocess/abrdf_matrix.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <sstream>
#include <vector>

#include "io/color.h"
#include "util/error.h"
#include "util/half.h"
#include "util/parallel.h"
#include "util/progress.h"

namespace nbtf {

// ---- Filling X from the image-major stack

MatrixXfCol abrdfMatrix(const BtfStack& stack, bool progress) {
  const Eigen::Index texels = stack.numTexels();
  const int images = stack.numImages();
  if (texels == 0 || images == 0) throw fileError(stack.source, "empty BTF stack: nothing to cluster");
  MatrixXfCol x(texels, 3 * static_cast<Eigen::Index>(images));
  Progress bar("abrdf matrix", images, progress);
  // One interleaved RGB image per worker at a time; column 3 * image + c is contiguous.
  const int workers = threadCount();
  std::vector<std::vector<float>> buffers(workers, std::vector<float>(static_cast<std::size_t>(texels) * 3));
  parallelForDynamic(images, [&](std::size_t image, int worker) {
    std::vector<float>& rgb = buffers[worker];
    stack.imageLinear(static_cast<int>(image), rgb.data());
    for (int c = 0; c < 3; ++c) {
      float* column = x.col(3 * static_cast<Eigen::Index>(image) + c).data();
      for (Eigen::Index t = 0; t < texels; ++t) column[t] = rgb[3 * t + c];
    }
    bar.advance();
  });
  bar.finish();
  return x;
}

// ---- Standardization

namespace {

// Dimensions whose spread is below float resolution of their values are constant: their
// "variance" is rounding noise, and dividing by it would blow noise up to unit scale.
bool isConstantDimension(double mean, double stddev) { return stddev <= 1e-6 * std::abs(mean); }

std::string describeDimension(Eigen::Index dim) {
  std::ostringstream s;
  s << "dimension " << dim << " (image " << dim / 3 << ", channel " << "RGB"[dim % 3] << ")";
  return s.str();
}

// log(x + 1) is defined for x > -1 only; a NaN or Inf here would silently poison PCA.
void checkLogDomain(const float* column, Eigen::Index rows, Eigen::Index dim) {
  auto values = Eigen::Map<const Eigen::ArrayXf>(column, rows);
  if (((values > -1.0f) && (values < std::numeric_limits<float>::infinity())).all()) return;  // NaN fails too
  for (Eigen::Index t = 0; t < rows; ++t) {
    float v = column[t];
    if (!std::isfinite(v) || v <= -1.0f) {
      std::ostringstream s;
      s << "ABRDF value " << v << " at texel " << t << ", " << describeDimension(dim)
        << " cannot be log-transformed (expected a finite linear value > -1)";
      throw Error(s.str());
    }
  }
}

// log(1 + x). With u = 1 + x (rounded), log(u) * x / (u - 1) cancels the rounding of u
// (Goldberg's formula) and keeps log1p's accuracy for tiny x.
float log1pValue(float x) {
  const float u = x + 1.0f;
  return u == 1.0f ? x : std::log(u) * (x / (u - 1.0f));
}

// log1pValue of every finite half >= 0, indexed by its bits: half and computed stacks hold
// halves only, and a look-up costs a tenth of the logarithm and the division.
const std::vector<float>& log1pOfHalves() {
  static const std::vector<float> table = [] {
    std::vector<float> t(0x7C00);
    for (std::uint32_t h = 0; h < t.size(); ++h) t[h] = log1pValue(halfToFloat(static_cast<std::uint16_t>(h)));
    return t;
  }();
  return table;
}

// log1pValue of a run of values, in place: x's half bits index the table when x is a half
// >= 0 (the same bits as computing it), otherwise computed.
void log1pInPlace(float* values, Eigen::Index n) {
  const float* table = log1pOfHalves().data();
  for (Eigen::Index i = 0; i < n; ++i) {
    const float x = values[i];
    std::uint32_t f;
    std::memcpy(&f, &x, 4);
    std::uint32_t h = 0x7C00;  // not a half >= 0
    if (f >= 0x38800000u && f <= 0x477FE000u && (f & 0x1FFFu) == 0) {
      h = (f >> 13) - 0x1C000u;  // normal: rebias the exponent from 127 to 15
    } else if (f < 0x38800000u) {  // below 2^-14: subnormal halves are multiples of 2^-24
      const float steps = x * 16777216.0f;
      if (steps == static_cast<float>(static_cast<std::uint32_t>(steps))) h = static_cast<std::uint32_t>(steps);
    }
    values[i] = h < 0x7C00 ? table[h] : log1pValue(x);
  }
}

// exp(y) - 1, the inverse, with Kahan's correction (u - 1) * y / log(u), u = exp(y), for
// the same reason.
void expm1InPlace(float* values, Eigen::Index n) {
  auto y = Eigen::Map<Eigen::ArrayXf>(values, n);
  Eigen::ArrayXf u = y.exp();
  Eigen::ArrayXf corrected = (u - 1.0f) * (y / u.log());
  y = (u == 1.0f).select(y, (u - 1.0f == -1.0f || u == std::numeric_limits<float>::infinity()).select(u - 1.0f, corrected));
}

}  // namespace

void columnMoments(const float* column, Eigen::Index rows, double& mean, double& variance) {
  constexpr Eigen::Index kRun = 1024;
  const double n = static_cast<double>(rows);
  double sum = 0;
  for (Eigen::Index b = 0; b < rows; b += kRun) sum += Eigen::Map<const Eigen::ArrayXf>(column + b, std::min(kRun, rows - b)).sum();
  mean = sum / n;
  const float meanF = static_cast<float>(mean);
  double squares = 0;
  for (Eigen::Index b = 0; b < rows; b += kRun)
    squares += (Eigen::Map<const Eigen::ArrayXf>(column + b, std::min(kRun, rows - b)) - meanF).square().sum();
  variance = squares / n;
}

void Standardization::apply(MatrixXfCol& x) const {
  if (x.cols() != mean.size())
    throw Error("standardization: data has " + std::to_string(x.cols()) + " dimensions, the statistics have " +
                std::to_string(mean.size()));
  parallelFor(x.cols(), [&](std::size_t begin, std::size_t end) {
    for (std::size_t d = begin; d < end; ++d) {
      checkLogDomain(x.col(d).data(), x.rows(), d);
      auto col = x.col(d).array();
      if (stddev[d] > 0) {
        log1pInPlace(x.col(d).data(), x.rows());
        col = (col - mean[d]) * (1.0f / stddev[d]);
      } else {
        col = 0.0f;
      }
    }
  });
}

void Standardization::applyRow(float* row) const {
  for (Eigen::Index d = 0; d < mean.size(); ++d) checkLogDomain(row + d, 1, d);
  log1pInPlace(row, mean.size());
  for (Eigen::Index d = 0; d < mean.size(); ++d) row[d] = stddev[d] > 0 ? (row[d] - mean[d]) * (1.0f / stddev[d]) : 0.0f;
}

void Standardization::invert(MatrixXfCol& z) const {
  if (z.cols() != mean.size())
    throw Error("standardization: data has " + std::to_string(z.cols()) + " dimensions, the statistics have " +
                std::to_string(mean.size()));
  parallelFor(z.cols(), [&](std::size_t begin, std::size_t end) {
    for (std::size_t d = begin; d < end; ++d) {
      auto col = z.col(d).array();
      col = col * stddev[d] + mean[d];
      expm1InPlace(z.col(d).data(), z.rows());
    }
  });
}

namespace {

// One column of linear values (contiguous, cache-resident): log, two-pass mean and variance
// in double, then scaled in place. The float sums run over Eigen maps whose vectorized
// reduction depends on the column's address modulo the SIMD alignment, so callers that
// stream (fitStandardization) lay columns out at the address offsets X would give them.
// standardizeLoggedColumn is its second half, for a column that already holds log(x + 1).
void standardizeLoggedColumn(float* column, Eigen::Index rows, float& meanOut, float& stddevOut) {
  auto col = Eigen::Map<Eigen::ArrayXf>(column, rows);
  double mean, variance;
  columnMoments(column, rows, mean, variance);
  double stddev = std::sqrt(variance);
  if (isConstantDimension(mean, stddev)) stddev = 0;
  meanOut = static_cast<float>(mean);
  stddevOut = static_cast<float>(stddev);
  // Exactly the arithmetic of apply(), so fitting and re-applying agree bit for bit.
  if (stddev > 0)
    col = (col - meanOut) * (1.0f / stddevOut);
  else
    col = 0.0f;
}

void standardizeColumn(float* column, Eigen::Index rows, Eigen::Index d, float& meanOut, float& stddevOut) {
  checkLogDomain(column, rows, d);
  log1pInPlace(column, rows);
  standardizeLoggedColumn(column, rows, meanOut, stddevOut);
}

}  // namespace

Standardization standardizeInPlace(MatrixXfCol& x) {
  if (x.rows() == 0 || x.cols() == 0) throw Error("standardization: empty ABRDF matrix");
  Standardization s;
  s.mean.resize(x.cols());
  s.stddev.resize(x.cols());
  // Per column: one pass over memory, no second copy of X.
  parallelFor(x.cols(), [&](std::size_t begin, std::size_t end) {
    for (std::size_t d = begin; d < end; ++d) standardizeColumn(x.col(d).data(), x.rows(), d, s.mean[d], s.stddev[d]);
  });
  return s;
}

namespace {
float alphaFromMaximum(const BtfStack& stack, float hi) {
  if (!(hi > 0))
    throw fileError(stack.source.empty() ? std::string("BTF stack") : stack.source,
                    "every value is zero: no maximum to normalize the targets by");
  return hi;
}
}  // namespace

Standardization fitStandardization(const BtfStack& stack, bool progress, float* alpha, ColumnMoments* standardized) {
  const Eigen::Index texels = stack.numTexels(), dims = 3 * static_cast<Eigen::Index>(stack.numImages());
  if (texels == 0 || dims == 0) throw fileError(stack.source, "empty BTF stack: nothing to cluster");
  Standardization s;
  s.mean.resize(dims);
  s.stddev.resize(dims);
  // One image (3 columns) per task, each column placed at the offset modulo the SIMD width
  // that column 3 * image + c has in X (Eigen aligns X's start), so that the vectorized sums
  // add the same values in the same order as standardizeInPlace: identical statistics.
  constexpr Eigen::Index kAlign = 16 / sizeof(float);
  const int workers = threadCount();
  std::vector<Eigen::VectorXf> buffers(workers);
  std::vector<std::vector<float>> images(workers);
  std::vector<float> highest(workers, -std::numeric_limits<float>::infinity());
  if (standardized) standardized->mean.resize(dims), standardized->variance.resize(dims);
  // An 8-bit stack holds 256 values: their logarithms (log1pInPlace works value by value, so a
  // table gives its bits) spare a logarithm per sample, most of this pass's time otherwise.
  const bool srgb = stack.sampleType() == SampleType::Srgb8 && !stack.isComputed();
  const float* linear = srgb8ToLinearTable();
  const std::vector<float> logs = log1pOfSrgb8();
  std::vector<std::vector<std::uint8_t>> copies(workers);  // 8-bit images read out of a scratch file
  Progress bar("standardize", stack.numImages(), progress);
  parallelForDynamic(stack.numImages(), [&](std::size_t image, int worker) {
    Eigen::VectorXf& buffer = buffers[worker];
    std::vector<float>& rgb = images[worker];
    if (buffer.size() == 0) buffer.resize(texels + kAlign);
    const std::uint8_t* bytes = nullptr;
    if (srgb) {
      bytes = stack.readImageBytes(static_cast<int>(image), 0, stack.bytesPerImage(), copies[worker]);
      // The table rises with the byte: the largest byte's value is the image's maximum.
      if (alpha) highest[worker] = std::max(highest[worker], linear[*std::max_element(bytes, bytes + 3 * texels)]);
    } else {
      if (rgb.empty()) rgb.resize(static_cast<std::size_t>(texels) * 3);
      stack.imageLinear(static_cast<int>(image), rgb.data());
      if (alpha) highest[worker] = std::max(highest[worker], *std::max_element(rgb.begin(), rgb.end()));
    }
    for (int c = 0; c < 3; ++c) {
      const Eigen::Index d = 3 * static_cast<Eigen::Index>(image) + c;
      float* column = buffer.data() + (d * texels) % kAlign;
      if (srgb) {
        for (Eigen::Index t = 0; t < texels; ++t) column[t] = logs[bytes[3 * t + c]];
        standardizeLoggedColumn(column, texels, s.mean[d], s.stddev[d]);
      } else {
        for (Eigen::Index t = 0; t < texels; ++t) column[t] = rgb[3 * t + c];
        standardizeColumn(column, texels, d, s.mean[d], s.stddev[d]);
      }
      if (standardized) {  // the standardized column, where X would hold it: PCA's moments
        double mean;
        columnMoments(column, texels, mean, standardized->variance[d]);
        standardized->mean[d] = static_cast<float>(mean);
      }
    }
    bar.advance();
  });
  bar.finish();
  if (alpha) *alpha = alphaFromMaximum(stack, *std::max_element(highest.begin(), highest.end()));
  return s;
}

void log1pRun(float* values, Eigen::Index n) { log1pInPlace(values, n); }

std::vector<float> log1pOfSrgb8() {
  const float* linear = srgb8ToLinearTable();
  std::vector<float> logs(linear, linear + 256);
  log1pInPlace(logs.data(), 256);
  return logs;
}

// ---- Target normalization

float targetAlpha(const BtfStack& stack) {
  float lo, hi;
  stack.valueRange(lo, hi);
  return alphaFromMaximum(stack, hi);
}

}  // namespace nbtf
