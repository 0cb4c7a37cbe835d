#include "model/decoder_backprop.h"

#include <ATen/Parallel.h>

#include <algorithm>

#include "model/dynamic_items.h"
#include "util/simd.h"

namespace nbtf::detail {
namespace {

// Rows per chunk: 512 rows x 112 floats = 229 KB per activation, so a chunk's activations
// and gradients stay in a core's L2 through the whole forward and backward pass.
constexpr int kChunkRows = 512;

// ---- Layer 0 (element-wise, cloned per instruction set). Rows have stride S >= W + 1.

// h[r] = relu(tile[r / rowsPerTile] + W_d d[r]) for rows r0 .. r0 + n (D direction inputs
// per row), then the constant-1 column at W and zeros up to S. The first 4 inputs (the
// paper's) go in one unrolled sum; wider encodings add the rest one input at a time.
NBTF_SIMD_CLONES void layer0Forward(int n, int W, int S, int D, std::int64_t r0, int rowsPerTile,
                                    const float* __restrict tiles, const float* __restrict d,
                                    const float* __restrict w0T, float* __restrict h) {
  for (int r = 0; r < n; ++r) {
    const float* __restrict a = tiles + ((r0 + r) / rowsPerTile) * W;
    const float* dr = d + static_cast<std::size_t>(D) * r;
    float* __restrict hr = h + static_cast<std::size_t>(r) * S;
    const float d0 = dr[0], d1 = dr[1], d2 = dr[2], d3 = dr[3];
    for (int j = 0; j < W; ++j) hr[j] = a[j] + d0 * w0T[j] + d1 * w0T[W + j] + d2 * w0T[2 * W + j] + d3 * w0T[3 * W + j];
    for (int q = 4; q < D; ++q) {
      const float dq = dr[q];
      const float* __restrict wq = w0T + static_cast<std::size_t>(q) * W;
      for (int j = 0; j < W; ++j) hr[j] += dq * wq[j];
    }
    for (int j = 0; j < W; ++j) hr[j] = hr[j] > 0 ? hr[j] : 0;
    hr[W] = 1.0f;
    for (int j = W + 1; j < S; ++j) hr[j] = 0.0f;
  }
}

// Layer 0's gradient: per tile (sum of its rows; tileGrad starts at tile firstTile) and per
// direction input (transposed). One stream per loop and restrict-qualified pointers, so every
// loop vectorizes.
NBTF_SIMD_CLONES void layer0Backward(int n, int W, int S, int D, std::int64_t r0, int rowsPerTile, std::int64_t firstTile,
                                     const float* __restrict g, const float* __restrict d,
                                     float* __restrict tileGrad, float* __restrict dirGradT) {
  for (int r = 0; r < n; ++r) {
    const float* __restrict gr = g + static_cast<std::size_t>(r) * S;
    float* __restrict t = tileGrad + ((r0 + r) / rowsPerTile - firstTile) * W;
    for (int j = 0; j < W; ++j) t[j] += gr[j];
    for (int q = 0; q < D; ++q) {
      const float dq = d[static_cast<std::size_t>(D) * r + q];
      float* __restrict dg = dirGradT + q * W;
      for (int j = 0; j < W; ++j) dg[j] += dq * gr[j];
    }
  }
}

// The gradient of the last P direction inputs of rows r0 .. r0 + n: row r's dLoss/d(input)
// = sum_j g[r, j] W_d[j, last P] (wTrail: those P columns of W_d, W x P). Accumulated along
// the P outputs, so the inner loop vectorizes without reordering a sum.
NBTF_SIMD_CLONES void layer0InputGradient(int n, int W, int S, int P, const float* __restrict g,
                                          const float* __restrict wTrail, float* __restrict out) {
  for (int r = 0; r < n; ++r) {
    const float* __restrict gr = g + static_cast<std::size_t>(r) * S;
    float* __restrict o = out + static_cast<std::size_t>(r) * P;
    for (int p = 0; p < P; ++p) o[p] = 0;
    for (int j = 0; j < W; ++j) {
      const float gj = gr[j];
      const float* __restrict w = wTrail + static_cast<std::size_t>(j) * P;
      for (int p = 0; p < P; ++p) o[p] += gj * w[p];
    }
  }
}

}  // namespace

DecoderBackprop::DecoderBackprop(Decoder decoder, int latentDim) : decoder_(std::move(decoder)), latentDim_(latentDim) {
  layers_ = static_cast<int>(decoder_->layers.size());
  width_ = static_cast<int>(decoder_->layers[0]->weight.size(0));
  outputs_ = static_cast<int>(decoder_->layers[layers_ - 1]->weight.size(0));
  dirWidth_ = static_cast<int>(decoder_->layers[0]->weight.size(1)) - latentDim_;
  TORCH_CHECK(dirWidth_ >= 4, "decoder: the first layer needs the latent and at least 4 direction inputs");
  TORCH_CHECK(layers_ >= 2, "decoder: needs at least two layers");
  stride_ = paddedWidth(width_ + 1);
  std::size_t offset = 0;
  gradOffset_.assign(layers_, 0);
  forward_.resize(layers_);
  backward_.resize(layers_);
  for (int l = 0; l < layers_; ++l) {
    const auto& lin = decoder_->layers[l];
    TORCH_CHECK(lin->weight.is_contiguous() && lin->weight.scalar_type() == torch::kFloat, "decoder: float weights");
    weightGrad_.push_back(torch::zeros_like(lin->weight));
    biasGrad_.push_back(torch::zeros_like(lin->bias));
    if (l == 0) continue;
    TORCH_CHECK(lin->weight.size(1) == width_ && (l + 1 == layers_ || lin->weight.size(0) == width_),
                "decoder: hidden layers must all have the same width");
    gradOffset_[l] = offset;
    offset += static_cast<std::size_t>(lin->weight.size(0)) * stride_;
  }
  gradOffset_.push_back(offset);
}

void DecoderBackprop::runChunk(Worker& k, std::int64_t c, std::int64_t rows, int rowsPerTile, const float* dirs,
                              const float* targets, float* outRows) {
  const int W = width_, S = stride_, L = layers_, O = outputs_;
  const bool train = targets != nullptr;
  const float* tileBase = perTile_.data_ptr<float>();
  const float scale = static_cast<float>(2.0 / (static_cast<double>(O) * rows));  // d(mean squared error)/d(out)
  const std::size_t chunkFloats = static_cast<std::size_t>(kChunkRows) * S;
  if (k.hidden.size() != (L - 1) * chunkFloats) k.hidden.assign((L - 1) * chunkFloats, 0.0f);
  if (k.grad.size() != chunkFloats) {
    k.grad.assign(chunkFloats, 0.0f);
    k.grad2.assign(chunkFloats, 0.0f);
  }
  k.out.resize(static_cast<std::size_t>(kChunkRows) * O);
  auto hidden = [&](int l) { return k.hidden.data() + l * chunkFloats; };

  const std::int64_t r0 = c * kChunkRows;
  const int n = static_cast<int>(std::min<std::int64_t>(kChunkRows, rows - r0));
  const int D = dirWidth_;
  const float* d = dirs + r0 * D;

  // ---- Forward. Layer 0: relu(W_d d + (W_z z + b)) with the bracket precomputed per tile.
  layer0Forward(n, W, S, D, r0, rowsPerTile, tileBase, d, dirWeightT_.data(), hidden(0));
  for (int l = 1; l + 1 < L; ++l) productRelu(n, W + 1, hidden(l - 1), S, forward_[l].data(), S, hidden(l));
  float* o = train ? k.out.data() : outRows + r0 * O;
  rowDots(n, O, hidden(L - 2), S, forward_[L - 1].data(), o);
  if (!train) return;

  // This chunk's sums, zeroed here, on the thread that fills them.
  ChunkSums& sums = chunkSums_[c];
  sums.weightGrad.assign(gradOffset_.back(), 0.0f);
  sums.dirGrad.assign(static_cast<std::size_t>(D) * W, 0.0f);
  sums.firstTile = r0 / rowsPerTile;
  sums.tileGrad.assign(static_cast<std::size_t>((r0 + n - 1) / rowsPerTile - sums.firstTile + 1) * W, 0.0f);

  // ---- Loss: o becomes dLoss/dout.
  const float* y = targets + r0 * O;
  double sse = 0;
  for (int i = 0; i < O * n; ++i) {
    float diff = o[i] - y[i];
    sse += static_cast<double>(diff) * diff;
    o[i] = diff * scale;
  }
  sums.loss = sse;

  // ---- Backward, top down: each layer's weight (and bias) gradient, then the gradient
  // below it through the layer and the ReLU under it.
  float* dW = sums.weightGrad.data();
  float *g = k.grad.data(), *g2 = k.grad2.data();
  accumulateOuter(n, O, o, O, hidden(L - 2), S, dW + gradOffset_[L - 1]);
  productMasked(n, O, o, O, backward_[L - 1].data(), S, hidden(L - 2), g);
  for (int l = L - 2; l >= 1; --l) {
    accumulateOuter(n, W, g, S, hidden(l - 1), S, dW + gradOffset_[l]);
    productMasked(n, W, g, S, backward_[l].data(), S, hidden(l - 1), g2);
    std::swap(g, g2);
  }
  // Layer 0: per tile (sum of its rows) for the latent part, per row for the directions.
  layer0Backward(n, W, S, D, r0, rowsPerTile, sums.firstTile, g, d, sums.tileGrad.data(), sums.dirGrad.data());
  if (trailingInputs_ > 0)
    layer0InputGradient(n, W, S, trailingInputs_, g, trailingWeights_.data(),
                        inputGradient_.data() + static_cast<std::size_t>(r0) * trailingInputs_);
}

void DecoderBackprop::run(const torch::Tensor& z, const torch::Tensor& dirs, const float* targets, int rowsPerTile,
                          float* outRows) {
  const std::int64_t tiles = z.size(0), rows = dirs.size(0);
  TORCH_CHECK(rows == tiles * rowsPerTile, "decoder: rows must be tiles x rowsPerTile");
  const int W = width_, S = stride_, L = layers_, D = dirWidth_;
  TORCH_CHECK(dirs.is_contiguous() && dirs.size(1) == D, "decoder: dirs must be contiguous [rows, direction inputs]");
  const torch::Tensor& w0 = decoder_->layers[0]->weight;
  // Per-tile part of layer 0 and the direction weights, transposed for row-wise use.
  perTile_ = torch::addmm(decoder_->layers[0]->bias, z, w0.narrow(1, 0, latentDim_).t()).contiguous();
  dirWeightT_.resize(static_cast<std::size_t>(D) * W);
  const float* w0p = w0.data_ptr<float>();
  for (int j = 0; j < W; ++j)
    for (int q = 0; q < D; ++q) dirWeightT_[q * W + j] = w0p[static_cast<std::size_t>(j) * (latentDim_ + D) + latentDim_ + q];
  trailingWeights_.resize(static_cast<std::size_t>(W) * trailingInputs_);
  for (int j = 0; j < W; ++j)
    for (int p = 0; p < trailingInputs_; ++p)
      trailingWeights_[static_cast<std::size_t>(j) * trailingInputs_ + p] =
          w0p[static_cast<std::size_t>(j) * (latentDim_ + D) + latentDim_ + D - trailingInputs_ + p];
  // The padded weights of layers 1 .. L - 1 (see the header).
  for (int l = 1; l < L; ++l) {
    const auto& lin = decoder_->layers[l];
    const int out = static_cast<int>(lin->weight.size(0));
    const float* wl = lin->weight.data_ptr<float>();
    const float* bl = lin->bias.data_ptr<float>();
    AlignedFloats& f = forward_[l];
    AlignedFloats& b = backward_[l];
    b.assign(static_cast<std::size_t>(out) * S, 0.0f);
    for (int i = 0; i < out; ++i) std::copy_n(wl + static_cast<std::size_t>(i) * W, W, b.data() + static_cast<std::size_t>(i) * S);
    if (l + 1 == L) {  // rowDots: W padded, with the bias in the 1 column
      f.assign(static_cast<std::size_t>(out) * S, 0.0f);
      std::copy_n(b.data(), b.size(), f.data());
      for (int i = 0; i < out; ++i) f.data()[static_cast<std::size_t>(i) * S + W] = bl[i];
      continue;
    }
    f.assign(static_cast<std::size_t>(W + 1) * S, 0.0f);
    for (int q = 0; q < W; ++q)
      for (int i = 0; i < out; ++i) f.data()[static_cast<std::size_t>(q) * S + i] = wl[static_cast<std::size_t>(i) * W + q];
    for (int i = 0; i < out; ++i) f.data()[static_cast<std::size_t>(W) * S + i] = bl[i];
    f.data()[static_cast<std::size_t>(W) * S + W] = 1.0f;  // the 1 column maps to itself
  }

  const std::int64_t chunks = (rows + kChunkRows - 1) / kChunkRows;
  workers_.resize(dynamicSlots(chunks));
  if (targets) chunkSums_.resize(chunks);
  const float* d = dirs.data_ptr<float>();
  forEachItemDynamic(chunks, [&](int slot, const auto& take) {
    for (std::int64_t c = take(); c >= 0; c = take()) runChunk(workers_[slot], c, rows, rowsPerTile, d, targets, outRows);
  });
}

torch::Tensor DecoderBackprop::forward(const torch::Tensor& z, const torch::Tensor& dirs, int rowsPerTile) {
  torch::NoGradGuard noGrad;
  const std::int64_t rows = dirs.size(0);
  if (!out_.defined() || out_.size(0) != rows) out_ = torch::empty({rows, static_cast<std::int64_t>(outputs_)});
  run(z.contiguous(), dirs.contiguous(), nullptr, rowsPerTile, out_.data_ptr<float>());
  return out_;
}

double DecoderBackprop::trainStep(const torch::Tensor& z, const torch::Tensor& dirs, const torch::Tensor& targets,
                                  int rowsPerTile, torch::Tensor& dz) {
  torch::NoGradGuard noGrad;
  const std::int64_t rows = dirs.size(0);
  torch::Tensor zc = z.contiguous(), y = targets.contiguous();
  TORCH_CHECK(y.size(0) == rows && y.size(1) == outputs_, "decoder: targets must be [rows, outputs]");
  TORCH_CHECK(rows > 0, "decoder: a training step needs at least one row");
  TORCH_CHECK(trailingInputs_ <= dirWidth_, "decoder: more input gradients asked for than direction inputs");
  inputGradient_.resize(static_cast<std::size_t>(rows) * trailingInputs_);
  run(zc, dirs.contiguous(), y.data_ptr<float>(), rowsPerTile, nullptr);

  // Add the chunks' sums in chunk order (deterministic): the weight gradients on all threads,
  // each over a range of entries, into chunk 0's.
  const int W = width_, S = stride_, L = layers_, D = dirWidth_;
  const std::int64_t tiles = zc.size(0), chunks = static_cast<std::int64_t>(chunkSums_.size());
  float* sumW = chunkSums_[0].weightGrad.data();
  at::parallel_for(0, static_cast<std::int64_t>(gradOffset_.back()), 2048, [&](std::int64_t begin, std::int64_t end) {
    for (std::int64_t c = 1; c < chunks; ++c) {
      const float* __restrict w = chunkSums_[c].weightGrad.data();
      for (std::int64_t i = begin; i < end; ++i) sumW[i] += w[i];
    }
  });
  std::vector<float> dirGrad(static_cast<std::size_t>(D) * W, 0.0f), tileGradSum(static_cast<std::size_t>(tiles) * W, 0.0f);
  double loss = 0;
  for (const ChunkSums& sums : chunkSums_) {
    for (std::size_t i = 0; i < dirGrad.size(); ++i) dirGrad[i] += sums.dirGrad[i];
    float* t = tileGradSum.data() + sums.firstTile * W;
    for (std::size_t i = 0; i < sums.tileGrad.size(); ++i) t[i] += sums.tileGrad[i];
    loss += sums.loss;
  }
  for (int l = 1; l < L; ++l) {  // [out x stride] rows: the weights, then the bias in column W
    const float* g = sumW + gradOffset_[l];
    float* gw = weightGrad_[l].data_ptr<float>();
    float* gb = biasGrad_[l].data_ptr<float>();
    for (std::int64_t i = 0; i < weightGrad_[l].size(0); ++i) {
      std::copy_n(g + i * S, W, gw + i * W);
      gb[i] = g[i * S + W];
    }
  }
  // Layer 0 from the per-tile and per-direction sums.
  torch::Tensor tileGrad = torch::from_blob(tileGradSum.data(), {tiles, W});
  float* g0 = weightGrad_[0].data_ptr<float>();
  for (int j = 0; j < W; ++j)
    for (int q = 0; q < D; ++q) g0[static_cast<std::size_t>(j) * (latentDim_ + D) + latentDim_ + q] = dirGrad[q * W + j];
  weightGrad_[0].narrow(1, 0, latentDim_).copy_(torch::mm(tileGrad.t(), zc));
  torch::sum_out(biasGrad_[0], tileGrad, {0});
  dz = torch::mm(tileGrad, decoder_->layers[0]->weight.narrow(1, 0, latentDim_));

  for (int l = 0; l < L; ++l) {
    decoder_->layers[l]->weight.mutable_grad() = weightGrad_[l];
    decoder_->layers[l]->bias.mutable_grad() = biasGrad_[l];
  }
  return loss / (static_cast<double>(outputs_) * rows);
}

}  // namespace nbtf::detail
