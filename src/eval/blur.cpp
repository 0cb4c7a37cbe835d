#include "eval/blur.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "eval/metrics.h"
#include "util/error.h"

namespace nbtf {
namespace {
constexpr double kPi = 3.14159265358979323846;

// Source index of x + offset under the border rule.
inline int borderIndex(int i, int n, BlurBorder border) {
  if (border == BlurBorder::Clamp) return std::min(std::max(i, 0), n - 1);
  i %= n;
  return i < 0 ? i + n : i;
}

// One separable pass over an interleaved RGB image held as doubles or floats:
// out(x, y) = sum_t kernel[t] in(x + t - R, y) (horizontal) or in(x, y + t - R) (vertical).
template <class In>
void pass(const In* in, int width, int height, const std::vector<double>& kernel, bool horizontal,
          BlurBorder border, std::vector<double>& out) {
  const int radius = static_cast<int>(kernel.size() / 2);
  const int n = horizontal ? width : height;
  // Border-resolved source coordinates for every (position, tap).
  std::vector<int> source(static_cast<std::size_t>(n) * kernel.size());
  for (int i = 0; i < n; ++i)
    for (std::size_t t = 0; t < kernel.size(); ++t)
      source[i * kernel.size() + t] = borderIndex(i + static_cast<int>(t) - radius, n, border);
  out.assign(static_cast<std::size_t>(width) * height * 3, 0.0);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const int i = horizontal ? x : y;
      const int* src = &source[static_cast<std::size_t>(i) * kernel.size()];
      double r = 0, g = 0, b = 0;
      for (std::size_t t = 0; t < kernel.size(); ++t) {
        std::size_t p = horizontal ? (static_cast<std::size_t>(y) * width + src[t]) * 3
                                   : (static_cast<std::size_t>(src[t]) * width + x) * 3;
        double w = kernel[t];
        r += w * in[p], g += w * in[p + 1], b += w * in[p + 2];
      }
      std::size_t o = (static_cast<std::size_t>(y) * width + x) * 3;
      out[o] = r, out[o + 1] = g, out[o + 2] = b;
    }
  }
}

void checkImage(int width, int height, double sigma) {
  if (width <= 0 || height <= 0) throw Error("blur: image size must be positive");
  if (!(sigma > 0) || !std::isfinite(sigma)) throw Error("blur: sigma must be positive and finite");
}
}  // namespace

const char* blurBorderName(BlurBorder b) { return b == BlurBorder::Clamp ? "clamp" : "wrap"; }

// ---- Kernel

double gaussian2d(double s, double x, double y) {
  double r2 = x * x + y * y;
  return std::exp(-r2 / (2 * s * s)) / (2 * kPi * s * s);
}

double gaussian2dDSigma(double s, double x, double y) {
  double r2 = x * x + y * y;
  return (r2 - 2 * s * s) / (2 * kPi * std::pow(s, 5)) * std::exp(-r2 / (2 * s * s));
}

int blurKernelRadius(double sigma) { return std::max(1, static_cast<int>(std::ceil(4 * sigma))); }

void normalizedKernel1d(double s, int radius, std::vector<double>& k, std::vector<double>& dk) {
  // g(x) = exp(-x^2 / (2 s^2)); dg/ds = x^2 / s^3 g(x). For tiny s the off-centre taps
  // underflow to exactly 0 (never NaN: x^2 / s^3 stays finite for s >= 1e-100).
  const std::size_t taps = static_cast<std::size_t>(2 * radius + 1);
  std::vector<double> g(taps), dg(taps);
  double sum = 0, dsum = 0;
  for (int x = -radius; x <= radius; ++x) {
    double gx = std::exp(-double(x) * x / (2 * s * s));
    g[x + radius] = gx;
    dg[x + radius] = double(x) * x / (s * s * s) * gx;
    sum += gx, dsum += dg[x + radius];
  }
  k.resize(taps), dk.resize(taps);
  for (std::size_t t = 0; t < taps; ++t) {
    k[t] = g[t] / sum;
    dk[t] = (dg[t] - k[t] * dsum) / sum;  // derivative of g / sum g
  }
}

// ---- Blur, loss, gradient

void gaussianBlur(const float* rgb, int width, int height, double sigma, BlurBorder border, float* out) {
  checkImage(width, height, sigma);
  std::vector<double> k, dk, h, v;
  normalizedKernel1d(sigma, blurKernelRadius(sigma), k, dk);
  pass(rgb, width, height, k, true, border, h);
  pass(h.data(), width, height, k, false, border, v);
  for (std::size_t i = 0; i < v.size(); ++i) out[i] = static_cast<float>(v[i]);
}

double blurLoss(const float* reference, const float* reconstruction, int width, int height, float alpha,
                double sigma, BlurBorder border, double* gradient) {
  checkImage(width, height, sigma);
  std::vector<double> k, dk, h, hd, blurred, d1, d2;
  normalizedKernel1d(sigma, blurKernelRadius(sigma), k, dk);
  pass(reference, width, height, k, true, border, h);
  pass(h.data(), width, height, k, false, border, blurred);
  if (gradient) {
    // dK/ds = k'(x) k(y) + k(x) k'(y): two separable terms.
    pass(reference, width, height, dk, true, border, hd);
    pass(hd.data(), width, height, k, false, border, d1);
    pass(h.data(), width, height, dk, false, border, d2);
  }
  const double inv = 1.0 / alpha, n = static_cast<double>(blurred.size());
  double loss = 0, grad = 0;
  for (std::size_t i = 0; i < blurred.size(); ++i) {
    double diff = (blurred[i] - reconstruction[i]) * inv;
    loss += diff * diff;
    if (gradient) grad += 2 * diff * (d1[i] + d2[i]) * inv;  // dLoss/dc^ * dc^/ds
  }
  loss /= n;
  if (!std::isfinite(loss)) throw Error("blur: loss is not finite at sigma = " + std::to_string(sigma));
  if (gradient) *gradient = grad / n;
  return loss;
}

// ---- Estimation

BlurEstimate estimateBlur(const float* reference, const float* reconstruction, int width, int height, float alpha,
                          const BlurOptions& o) {
  if (!(o.minSigma > 0) || !(o.maxSigma > o.minSigma)) throw Error("blur: need 0 < minSigma < maxSigma");
  // A Gaussian wider than a quarter of the image says nothing more than "no detail left".
  const double maxSigma = std::max(2 * o.minSigma, std::min(o.maxSigma, 0.25 * std::max(width, height)));
  BlurEstimate est;
  const std::size_t n = static_cast<std::size_t>(width) * height * 3;
  est.rmseBefore = rmseLinear(reference, reconstruction, n, alpha);

  // Coarse grid for the starting point; ties keep the smaller sigma (no blur wins).
  double bestSigma = o.minSigma, bestLoss = blurLoss(reference, reconstruction, width, height, alpha, o.minSigma,
                                                     o.border, nullptr);
  if (o.startSigma > 0) {
    bestSigma = std::min(maxSigma, std::max(o.minSigma, o.startSigma));
    bestLoss = blurLoss(reference, reconstruction, width, height, alpha, bestSigma, o.border, nullptr);
  } else {
    for (double s : {0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 24.0, 32.0}) {
      if (s <= o.minSigma || s > maxSigma) continue;
      double l = blurLoss(reference, reconstruction, width, height, alpha, s, o.border, nullptr);
      if (l < bestLoss) bestLoss = l, bestSigma = s;
    }
  }
  est.initialSigma = bestSigma;

  // Adam on sigma (beta1 0.9, beta2 0.999, eps 1e-8: the source's settings).
  double sigma = bestSigma, m = 0, v = 0;
  const double beta1 = 0.9, beta2 = 0.999, eps = 1e-8;
  int quiet = 0;
  for (int t = 1; t <= o.maxIterations; ++t) {
    double grad = 0;
    double loss = blurLoss(reference, reconstruction, width, height, alpha, sigma, o.border, &grad);
    if (loss < bestLoss) bestLoss = loss, bestSigma = sigma;
    m = beta1 * m + (1 - beta1) * grad;
    v = beta2 * v + (1 - beta2) * grad * grad;
    double mHat = m / (1 - std::pow(beta1, t)), vHat = v / (1 - std::pow(beta2, t));
    double step = o.learningRate * mHat / (std::sqrt(vHat) + eps);
    // The change actually made: at a bound the gradient may keep pushing outward while
    // sigma stays put, which is convergence too.
    double next = std::min(maxSigma, std::max(o.minSigma, sigma - step));
    double moved = std::abs(next - sigma);
    sigma = next;
    est.iterations = t;
    quiet = moved < o.stepTolerance ? quiet + 1 : 0;
    if (quiet >= o.patience) {
      est.converged = true;
      break;
    }
  }
  double last = blurLoss(reference, reconstruction, width, height, alpha, sigma, o.border, nullptr);
  if (last < bestLoss) bestLoss = last, bestSigma = sigma;
  est.sigma = bestSigma;
  est.rmseAfter = std::sqrt(bestLoss);
  est.atUpperBound = bestSigma >= maxSigma * (1 - 1e-9);
  est.upperBound = maxSigma;
  return est;
}

}  // namespace nbtf
