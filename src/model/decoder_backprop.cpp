#include "model/decoder_backprop.h"

#include <ATen/Parallel.h>

#include <algorithm>

#include "model/simd_clones.h"

// The Fortran BLAS entry point (OpenBLAS here, see src/CMakeLists.txt). Called from inside
// a parallel region, the OpenMP build of OpenBLAS runs single-threaded, which is what we want.
extern "C" void sgemm_(const char* transa, const char* transb, const int* m, const int* n, const int* k,
                       const float* alpha, const float* a, const int* lda, const float* b, const int* ldb,
                       const float* beta, float* c, const int* ldc);

namespace nbtf::detail {
namespace {

// Rows per chunk: 512 rows x 106 floats = 217 KB per activation, so a chunk's activations
// and gradients stay in a core's L2 through the whole forward and backward pass.
constexpr int kChunkRows = 512;

// Row-major [rows x cols] is column-major [cols x rows]; the three products below are
// written for that view. W is row-major [out x in] (nn::Linear).
// y[rows x out] = x[rows x in] W^T
void forwardProduct(int rows, int in, int out, const float* x, const float* w, float* y) {
  const float one = 1, zero = 0;
  sgemm_("T", "N", &out, &rows, &in, &one, w, &in, x, &in, &zero, y, &out);
}
// dx[rows x in] = dy[rows x out] W
void inputGradient(int rows, int in, int out, const float* dy, const float* w, float* dx) {
  const float one = 1, zero = 0;
  sgemm_("N", "N", &in, &rows, &out, &one, w, &in, dy, &out, &zero, dx, &in);
}
// dW[out x in] += dy^T x
void accumulateWeightGradient(int rows, int in, int out, const float* dy, const float* x, float* dw) {
  const float one = 1;
  sgemm_("N", "T", &in, &out, &rows, &one, x, &in, dy, &out, &one, dw, &in);
}

// ---- Element-wise kernels: a fifth of a step at SSE2 width, hence the clones.

// h[r] = relu(tile[r / rowsPerTile] + W_d d[r]) for rows r0 .. r0 + n.
NBTF_SIMD_CLONES void layer0Forward(int n, int W, std::int64_t r0, int rowsPerTile, const float* __restrict tiles,
                                    const float* __restrict d, const float* __restrict w0T, float* __restrict h) {
  for (int r = 0; r < n; ++r) {
    const float* __restrict a = tiles + ((r0 + r) / rowsPerTile) * W;
    const float* dr = d + 4 * r;
    float* __restrict hr = h + static_cast<std::size_t>(r) * W;
    const float d0 = dr[0], d1 = dr[1], d2 = dr[2], d3 = dr[3];
    for (int j = 0; j < W; ++j) {
      float v = a[j] + d0 * w0T[j] + d1 * w0T[W + j] + d2 * w0T[2 * W + j] + d3 * w0T[3 * W + j];
      hr[j] = v > 0 ? v : 0;
    }
  }
}

// y = relu(y + b), row-wise.
NBTF_SIMD_CLONES void biasRelu(int n, int W, const float* __restrict b, float* __restrict y) {
  for (int r = 0; r < n; ++r) {
    float* __restrict yr = y + static_cast<std::size_t>(r) * W;
    for (int j = 0; j < W; ++j) {
      float v = yr[j] + b[j];
      yr[j] = v > 0 ? v : 0;
    }
  }
}

// g = g where h > 0 else 0 (the ReLU's backward); db += column sums of g (if given).
NBTF_SIMD_CLONES void reluBackward(int n, int W, const float* __restrict h, float* __restrict g,
                                   float* __restrict db) {
  for (int r = 0; r < n; ++r) {
    float* __restrict gr = g + static_cast<std::size_t>(r) * W;
    const float* __restrict hr = h + static_cast<std::size_t>(r) * W;
    for (int j = 0; j < W; ++j) gr[j] = hr[j] > 0 ? gr[j] : 0.0f;
    if (db)
      for (int j = 0; j < W; ++j) db[j] += gr[j];
  }
}

// Layer 0's gradient: per tile (sum of its rows) and per direction input (transposed).
// One stream per loop and restrict-qualified pointers, so every loop vectorizes.
NBTF_SIMD_CLONES void layer0Backward(int n, int W, std::int64_t r0, int rowsPerTile, const float* __restrict g,
                                     const float* __restrict d, float* __restrict tileGrad,
                                     float* __restrict dirGradT) {
  for (int r = 0; r < n; ++r) {
    const float* __restrict gr = g + static_cast<std::size_t>(r) * W;
    float* __restrict t = tileGrad + ((r0 + r) / rowsPerTile) * W;
    for (int j = 0; j < W; ++j) t[j] += gr[j];
    for (int q = 0; q < 4; ++q) {
      const float dq = d[4 * r + q];
      float* __restrict dg = dirGradT + q * W;
      for (int j = 0; j < W; ++j) dg[j] += dq * gr[j];
    }
  }
}

}  // namespace

DecoderBackprop::DecoderBackprop(Decoder decoder, int latentDim) : decoder_(std::move(decoder)), latentDim_(latentDim) {
  layers_ = static_cast<int>(decoder_->layers.size());
  width_ = static_cast<int>(decoder_->layers[0]->weight.size(0));
  std::int64_t w = 0, b = 0;
  for (auto& lin : decoder_->layers) {
    TORCH_CHECK(lin->weight.is_contiguous() && lin->weight.scalar_type() == torch::kFloat, "decoder: float weights");
    weightOffset_.push_back(w);
    biasOffset_.push_back(b);
    w += lin->weight.numel();
    b += lin->bias.numel();
    weightGrad_.push_back(torch::zeros_like(lin->weight));
    biasGrad_.push_back(torch::zeros_like(lin->bias));
  }
  weightOffset_.push_back(w);
  biasOffset_.push_back(b);
}

void DecoderBackprop::runWorker(int w, int workers, std::int64_t rows, int rowsPerTile, const float* dirs,
                                const float* targets, float* outRows) {
  Worker& k = workers_[w];
  const int W = width_, L = layers_;
  const std::int64_t chunks = (rows + kChunkRows - 1) / kChunkRows;
  const std::int64_t c0 = chunks * w / workers, c1 = chunks * (w + 1) / workers;
  const bool train = targets != nullptr;
  const float* tileBase = perTile_.data_ptr<float>();
  const float scale = static_cast<float>(2.0 / (3.0 * rows));  // d(mean squared error)/d(out)
  k.hidden.resize(static_cast<std::size_t>(L - 1) * kChunkRows * W);
  k.grad.resize(static_cast<std::size_t>(kChunkRows) * W);
  k.grad2.resize(k.grad.size());
  k.out.resize(static_cast<std::size_t>(kChunkRows) * 3);
  auto hidden = [&](int l) { return k.hidden.data() + static_cast<std::size_t>(l) * kChunkRows * W; };
  auto weight = [&](int l) { return decoder_->layers[l]->weight.data_ptr<float>(); };
  auto bias = [&](int l) { return decoder_->layers[l]->bias.data_ptr<float>(); };

  for (std::int64_t c = c0; c < c1; ++c) {
    const std::int64_t r0 = c * kChunkRows;
    const int n = static_cast<int>(std::min<std::int64_t>(kChunkRows, rows - r0));
    const float* d = dirs + r0 * 4;

    // ---- Forward. Layer 0: relu(W_d d + (W_z z + b)) with the bracket precomputed per tile.
    layer0Forward(n, W, r0, rowsPerTile, tileBase, d, dirWeightT_.data(), hidden(0));
    for (int l = 1; l + 1 < L; ++l) {
      float* y = hidden(l);
      forwardProduct(n, W, W, hidden(l - 1), weight(l), y);
      biasRelu(n, W, bias(l), y);
    }
    float* o = train ? k.out.data() : outRows + r0 * 3;
    forwardProduct(n, W, 3, hidden(L - 2), weight(L - 1), o);
    const float* bl = bias(L - 1);
    for (int r = 0; r < n; ++r)
      for (int j = 0; j < 3; ++j) o[3 * r + j] += bl[j];
    if (!train) continue;

    // ---- Loss: o becomes dLoss/dout.
    const float* y = targets + r0 * 3;
    double sse = 0;
    for (int i = 0; i < 3 * n; ++i) {
      float diff = o[i] - y[i];
      sse += static_cast<double>(diff) * diff;
      o[i] = diff * scale;
    }
    k.loss += sse;

    // ---- Backward, top down.
    float* dW = k.weightGrad.data();
    float* dB = k.biasGrad.data();
    accumulateWeightGradient(n, W, 3, o, hidden(L - 2), dW + weightOffset_[L - 1]);
    for (int r = 0; r < n; ++r)
      for (int j = 0; j < 3; ++j) dB[biasOffset_[L - 1] + j] += o[3 * r + j];
    float *g = k.grad.data(), *g2 = k.grad2.data();
    inputGradient(n, W, 3, o, weight(L - 1), g);
    for (int l = L - 2; l >= 0; --l) {
      // Through the ReLU (mask by the activation), then the bias gradient.
      reluBackward(n, W, hidden(l), g, l > 0 ? dB + biasOffset_[l] : nullptr);
      if (l == 0) break;
      accumulateWeightGradient(n, W, W, g, hidden(l - 1), dW + weightOffset_[l]);
      inputGradient(n, W, W, g, weight(l), g2);
      std::swap(g, g2);
    }
    // Layer 0: per tile (sum of its rows) for the latent part, per row for the directions.
    layer0Backward(n, W, r0, rowsPerTile, g, d, k.tileGrad.data(), k.dirGrad.data());
  }
}

void DecoderBackprop::run(const torch::Tensor& z, const torch::Tensor& dirs, const float* targets, int rowsPerTile,
                          float* outRows) {
  const std::int64_t tiles = z.size(0), rows = dirs.size(0);
  TORCH_CHECK(rows == tiles * rowsPerTile, "decoder: rows must be tiles x rowsPerTile");
  TORCH_CHECK(dirs.is_contiguous() && dirs.size(1) == 4, "decoder: dirs must be contiguous [rows, 4]");
  const int W = width_;
  const torch::Tensor& w0 = decoder_->layers[0]->weight;
  // Per-tile part of layer 0 and the direction weights, transposed for row-wise use.
  perTile_ = torch::addmm(decoder_->layers[0]->bias, z, w0.narrow(1, 0, latentDim_).t()).contiguous();
  dirWeightT_.resize(4 * static_cast<std::size_t>(W));
  const float* w0p = w0.data_ptr<float>();
  for (int j = 0; j < W; ++j)
    for (int q = 0; q < 4; ++q) dirWeightT_[q * W + j] = w0p[static_cast<std::size_t>(j) * (latentDim_ + 4) + latentDim_ + q];

  const int workers = std::max(1, std::min<int>(at::get_num_threads(), (rows + kChunkRows - 1) / kChunkRows));
  workers_.resize(workers);
  for (Worker& k : workers_) {
    if (!targets) break;
    k.weightGrad.assign(weightOffset_.back(), 0.0f);
    k.biasGrad.assign(biasOffset_.back(), 0.0f);
    k.dirGrad.assign(4 * static_cast<std::size_t>(W), 0.0f);
    k.tileGrad.assign(static_cast<std::size_t>(tiles) * W, 0.0f);
    k.loss = 0;
  }
  const float* d = dirs.data_ptr<float>();
  if (workers == 1) {
    runWorker(0, 1, rows, rowsPerTile, d, targets, outRows);
  } else {
    at::parallel_for(0, workers, 1, [&](std::int64_t begin, std::int64_t end) {
      for (std::int64_t w = begin; w < end; ++w) runWorker(static_cast<int>(w), workers, rows, rowsPerTile, d, targets, outRows);
    });
  }
}

torch::Tensor DecoderBackprop::forward(const torch::Tensor& z, const torch::Tensor& dirs, int rowsPerTile) {
  torch::NoGradGuard noGrad;
  const std::int64_t rows = dirs.size(0);
  if (!out_.defined() || out_.size(0) != rows) out_ = torch::empty({rows, 3});
  run(z.contiguous(), dirs.contiguous(), nullptr, rowsPerTile, out_.data_ptr<float>());
  return out_;
}

double DecoderBackprop::trainStep(const torch::Tensor& z, const torch::Tensor& dirs, const torch::Tensor& targets,
                                  int rowsPerTile, torch::Tensor& dz) {
  torch::NoGradGuard noGrad;
  const std::int64_t rows = dirs.size(0);
  torch::Tensor zc = z.contiguous(), y = targets.contiguous();
  TORCH_CHECK(y.size(0) == rows && y.size(1) == 3, "decoder: targets must be [rows, 3]");
  run(zc, dirs.contiguous(), y.data_ptr<float>(), rowsPerTile, nullptr);

  // Add the workers' sums in worker order (deterministic), into the parameters' grads.
  const int W = width_, L = layers_;
  Worker& sum = workers_[0];
  for (std::size_t w = 1; w < workers_.size(); ++w) {
    const Worker& k = workers_[w];
    for (std::size_t i = 0; i < sum.weightGrad.size(); ++i) sum.weightGrad[i] += k.weightGrad[i];
    for (std::size_t i = 0; i < sum.biasGrad.size(); ++i) sum.biasGrad[i] += k.biasGrad[i];
    for (std::size_t i = 0; i < sum.dirGrad.size(); ++i) sum.dirGrad[i] += k.dirGrad[i];
    for (std::size_t i = 0; i < sum.tileGrad.size(); ++i) sum.tileGrad[i] += k.tileGrad[i];
    sum.loss += k.loss;
  }
  for (int l = 1; l < L; ++l) {
    std::copy_n(sum.weightGrad.data() + weightOffset_[l], weightGrad_[l].numel(), weightGrad_[l].data_ptr<float>());
    std::copy_n(sum.biasGrad.data() + biasOffset_[l], biasGrad_[l].numel(), biasGrad_[l].data_ptr<float>());
  }
  // Layer 0 from the per-tile and per-direction sums.
  torch::Tensor tileGrad = torch::from_blob(sum.tileGrad.data(), {zc.size(0), W});
  float* g0 = weightGrad_[0].data_ptr<float>();
  for (int j = 0; j < W; ++j)
    for (int q = 0; q < 4; ++q) g0[static_cast<std::size_t>(j) * (latentDim_ + 4) + latentDim_ + q] = sum.dirGrad[q * W + j];
  weightGrad_[0].narrow(1, 0, latentDim_).copy_(torch::mm(tileGrad.t(), zc));
  torch::sum_out(biasGrad_[0], tileGrad, {0});
  dz = torch::mm(tileGrad, decoder_->layers[0]->weight.narrow(1, 0, latentDim_));

  for (int l = 0; l < L; ++l) {
    decoder_->layers[l]->weight.mutable_grad() = weightGrad_[l];
    decoder_->layers[l]->bias.mutable_grad() = biasGrad_[l];
  }
  return sum.loss / (3.0 * rows);
}

}  // namespace nbtf::detail
