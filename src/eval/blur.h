// Effective blur: the Gaussian filter strength sigma (in texels) that, applied to the
// reference image, best matches the reconstruction in the MSE sense. Neural BTF
// reconstructions look blurred; sigma puts a number on "how blurred".
//
// The estimate follows the differentiable Gaussian filter of the modular differentiable
// renderer's paper: sigma is learned by gradient descent (Adam, learning rate 1e-2 as in the
// source) on
//   Loss(s) = mean over texels and channels of (blur_s(ref) / alpha - rec / alpha)^2,
// with dLoss/ds = sum_ij dLoss/dc^_ij * sum_xy c_{i+x,j+y} dK(s,x,y)/ds  (eq. 4).
//
// Kernel. The continuous G(s,x,y) = exp(-(x^2+y^2)/(2 s^2)) / (2 pi s^2) of eq. (5) is
// sampled at integer offsets |x|, |y| <= R = ceil(4 s) and normalized to sum 1:
// K = G / S, S = sum G. Without normalization a small s would brighten the image (G(0,0)
// = 1/(2 pi s^2) > 1 for s < 0.4) and the estimate would trade blur for gain. The
// derivative of the normalized kernel is dK/ds = (dG/ds - K sum dG/ds) / S, with dG/ds
// exactly eq. (5): (x^2 + y^2 - 2 s^2) / (2 pi s^5) exp(-(x^2+y^2)/(2 s^2)). Because
// G(s,x,y) = g(x) g(y) up to a constant, K = k(x) k(y) with k the normalized 1-D kernel, so
// blur and derivative are computed separably (cheap for large s); the test checks the
// separable derivative against eq. (5) directly.
//
// Borders: clamp to edge. The paper's materials are 100 x 100 crops, which do not tile,
// so wrap-around would blur opposite edges into each other; wrap is available for whole,
// tileable textures.
//
// Small sigma: below ~0.3 texels the sampled kernel is a delta to float precision
// (neighbour weight exp(-1/(2 s^2)) < 0.4%), so the loss is flat there and any sigma under
// that floor means "no measurable blur". Sigma is kept in [minSigma, maxSigma].
#pragma once
#include <vector>

namespace nbtf {

enum class BlurBorder { Clamp, Wrap };
const char* blurBorderName(BlurBorder b);

// ---- The kernel (eq. 5)
double gaussian2d(double sigma, double x, double y);            // G
double gaussian2dDSigma(double sigma, double x, double y);      // dG/dsigma, eq. (5)
// ceil(4 sigma), at least 1. Four, not three, sigmas: the taps that appear when R grows
// then weigh exp(-8) of the centre instead of exp(-4.5), so the loss is nearly continuous in s.
int blurKernelRadius(double sigma);
// Normalized 1-D kernel k (2R+1 taps, sums to 1) and its derivative dk/dsigma; the 2-D
// kernel is k(x) k(y) and its derivative k'(x) k(y) + k(x) k'(y).
void normalizedKernel1d(double sigma, int radius, std::vector<double>& k, std::vector<double>& dk);

// Blurs an interleaved RGB float image (w x h x 3) with the normalized Gaussian.
void gaussianBlur(const float* rgb, int width, int height, double sigma, BlurBorder border, float* out);

// Loss(sigma) as above (linear values divided by alpha) and, if gradient != nullptr, dLoss/dsigma.
double blurLoss(const float* reference, const float* reconstruction, int width, int height, float alpha,
                double sigma, BlurBorder border, double* gradient);

struct BlurOptions {
  BlurBorder border = BlurBorder::Clamp;
  double learningRate = 1e-2;  // Adam, as in the differentiable Gaussian filter's paper
  int maxIterations = 800;
  double minSigma = 1e-3;
  double maxSigma = 16;  // also capped at a quarter of the image's larger side
  // Stop once the Adam step stayed below this (texels) for `patience` iterations.
  double stepTolerance = 2e-4;
  int patience = 20;
  // Starting sigma for Adam; 0 = the best point of the coarse grid.
  double startSigma = 0;
};

struct BlurEstimate {
  double sigma = 0;       // texels
  double rmseBefore = 0;  // RMSE(ref, rec), linear alpha-normalized
  double rmseAfter = 0;   // RMSE(blur_sigma(ref), rec), same space
  double initialSigma = 0;
  int iterations = 0;
  bool converged = false;  // stopped by the step tolerance, not the iteration cap
  // sigma reached the largest allowed value (min(maxSigma, image side / 4)): the
  // reconstruction keeps no detail at any scale the estimate can measure.
  bool atUpperBound = false;
  double upperBound = 0;
};

// Estimates sigma for one image pair. Starts Adam from the best sigma of a coarse grid
// (0.25 .. maxSigma) so a far-away optimum does not cost thousands of 1e-2 steps; returns
// the lowest-loss sigma seen. Deterministic.
BlurEstimate estimateBlur(const float* reference, const float* reconstruction, int width, int height, float alpha,
                          const BlurOptions& options = {});

}  // namespace nbtf
