#include "preprocess/abrdf_matrix.h"

#include <cmath>
#include <sstream>
#include <vector>

#include "util/error.h"
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

}  // namespace

void Standardization::apply(MatrixXfCol& x) const {
  if (x.cols() != mean.size())
    throw Error("standardization: data has " + std::to_string(x.cols()) + " dimensions, the statistics have " +
                std::to_string(mean.size()));
  parallelFor(x.cols(), [&](std::size_t begin, std::size_t end) {
    for (std::size_t d = begin; d < end; ++d) {
      checkLogDomain(x.col(d).data(), x.rows(), d);
      auto col = x.col(d).array();
      if (stddev[d] > 0)
        col = ((col.log1p() - mean[d]) * (1.0f / stddev[d]));
      else
        col = 0.0f;
    }
  });
}

void Standardization::applyRow(float* row) const {
  for (Eigen::Index d = 0; d < mean.size(); ++d) {
    checkLogDomain(row + d, 1, d);
    row[d] = stddev[d] > 0 ? (std::log1p(row[d]) - mean[d]) / stddev[d] : 0.0f;
  }
}

void Standardization::invert(MatrixXfCol& z) const {
  if (z.cols() != mean.size())
    throw Error("standardization: data has " + std::to_string(z.cols()) + " dimensions, the statistics have " +
                std::to_string(mean.size()));
  parallelFor(z.cols(), [&](std::size_t begin, std::size_t end) {
    for (std::size_t d = begin; d < end; ++d) {
      auto col = z.col(d).array();
      col = (col * stddev[d] + mean[d]).exp() - 1.0f;
    }
  });
}

Standardization standardizeInPlace(MatrixXfCol& x) {
  if (x.rows() == 0 || x.cols() == 0) throw Error("standardization: empty ABRDF matrix");
  Standardization s;
  s.mean.resize(x.cols());
  s.stddev.resize(x.cols());
  const double rows = static_cast<double>(x.rows());
  // Per column (contiguous, cache-resident): log, two-pass mean and variance in double,
  // then scale. One pass over memory, no second copy of X.
  parallelFor(x.cols(), [&](std::size_t begin, std::size_t end) {
    for (std::size_t d = begin; d < end; ++d) {
      float* column = x.col(d).data();
      checkLogDomain(column, x.rows(), d);
      auto col = x.col(d).array();
      col = col.log1p();
      double sum = 0;
      for (Eigen::Index t = 0; t < x.rows(); ++t) sum += column[t];
      double mean = sum / rows, squares = 0;
      for (Eigen::Index t = 0; t < x.rows(); ++t) squares += (column[t] - mean) * (column[t] - mean);
      double stddev = std::sqrt(squares / rows);
      if (isConstantDimension(mean, stddev)) stddev = 0;
      s.mean[d] = static_cast<float>(mean);
      s.stddev[d] = static_cast<float>(stddev);
      // Exactly the arithmetic of apply(), so fitting and re-applying agree bit for bit.
      if (stddev > 0)
        col = (col - s.mean[d]) * (1.0f / s.stddev[d]);
      else
        col = 0.0f;
    }
  });
  return s;
}

// ---- Target normalization

float targetAlpha(const BtfStack& stack) {
  float lo, hi;
  stack.valueRange(lo, hi);
  if (!(hi > 0))
    throw fileError(stack.source.empty() ? std::string("BTF stack") : stack.source,
                    "every value is zero: no maximum to normalize the targets by");
  return hi;
}

}  // namespace nbtf
