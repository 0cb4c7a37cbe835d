#include "model/autograd/decoder_backprop.h"

#include <ATen/Parallel.h>

#include <algorithm>

#include "model/autograd/dynamic_items.h"
#include "util/simd.h"

namespace nbtf::detail {
namespace {

// Rows per chunk: 512 rows x 112 floats = 229 KB per activation, so a chunk's activations
// and gradients stay in a core's L2 through the whole forward and backward pass.
constexpr int kChunkRows = 512;

// ---- Layer 0. Its direction part is a register-blocked product like the other layers':
// the chunk's direction inputs with a 1 column appended, times W_d^T with the tile's
// W_z z + b as its last row (set per tile: rows of one tile are contiguous).

// The chunk's direction inputs, each row followed by the constant 1 (row stride D + 1).
void appendOneColumn(int n, int D, const float* __restrict d, float* __restrict x) {
  for (int r = 0; r < n; ++r) {
    std::copy_n(d + static_cast<std::size_t>(D) * r, D, x + static_cast<std::size_t>(D + 1) * r);
    x[static_cast<std::size_t>(D + 1) * r + D] = 1.0f;
  }
}

int evenUp(int k) { return k + k % 2; }

// Per tile of rows r0 .. r0 + n: the sum of its rows' gradients (tileGrad starts at tile
// firstTile). One stream per loop, so it vectorizes.
NBTF_SIMD_CLONES void sumTileGradients(int n, int W, int S, std::int64_t r0, int rowsPerTile, std::int64_t firstTile,
                                       const float* __restrict g, float* __restrict tileGrad) {
  for (int r = 0; r < n; ++r) {
    const float* __restrict gr = g + static_cast<std::size_t>(r) * S;
    float* __restrict t = tileGrad + ((r0 + r) / rowsPerTile - firstTile) * W;
    for (int j = 0; j < W; ++j) t[j] += gr[j];
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

// One piece: the forward pass, the loss and the backward pass work on the same chunk-sized
// buffers while they are in L2, each stage on the one before it.
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

  // ---- Forward. Layer 0: relu(W_d d + (W_z z + b)) with the bracket precomputed per tile;
  // its 1 column (column W of the tile row) gives the next layer's bias input.
  k.inputs.resize(static_cast<std::size_t>(kChunkRows) * (D + 1));
  appendOneColumn(n, D, d, k.inputs.data());
  k.layer0.assign(layer0_.begin(), layer0_.end());
  float* tileRow = k.layer0.data() + static_cast<std::size_t>(D) * S;
  for (int rs = 0; rs < n;) {
    const std::int64_t tile = (r0 + rs) / rowsPerTile;
    const int re = static_cast<int>(std::min<std::int64_t>(n, (tile + 1) * rowsPerTile - r0));
    std::copy_n(tileBase + tile * W, W, tileRow);
    productRelu(re - rs, D + 1, k.inputs.data() + static_cast<std::size_t>(rs) * (D + 1), D + 1, k.layer0.data(), S,
                hidden(0) + static_cast<std::size_t>(rs) * S);
    rs = re;
  }
  const bool bf16 = bf16_ && train;
  if (bf16) {
    k.rows.resize(static_cast<std::size_t>(kChunkRows) * S);
    k.gradPairs.resize(static_cast<std::size_t>(kChunkRows + 1) * S);
    k.hiddenPairs.resize(static_cast<std::size_t>(kChunkRows + 1) * S);
  }
  for (int l = 1; l + 1 < L; ++l) {
    if (!bf16) {
      productRelu(n, W + 1, hidden(l - 1), S, forward_[l].data(), S, hidden(l));
      continue;
    }
    toBf16Rows(n, evenUp(W + 1), hidden(l - 1), S, k.rows.data(), S);
    productBf16(Bf16Epilogue::Relu, n, evenUp(W + 1), k.rows.data(), S, forwardBf16_[l].data(), S, nullptr, hidden(l));
  }
  float* o = train ? k.out.data() : outRows + r0 * O;
  rowDots(n, O, hidden(L - 2), S, forward_[L - 1].data(), o);
  if (!train) return;

  // This chunk's sums, zeroed here, on the thread that fills them.
  ChunkSums& sums = chunkSums_[c];
  sums.weightGrad.assign(gradOffset_.back(), 0.0f);
  sums.dirGrad.assign(static_cast<std::size_t>(D) * S, 0.0f);
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
    if (bf16) {
      toBf16RowPairs(n, S, g, S, k.gradPairs.data());
      toBf16RowPairs(n, S, hidden(l - 1), S, k.hiddenPairs.data());
      accumulateOuterBf16(n, W, k.gradPairs.data(), S, k.hiddenPairs.data(), S, dW + gradOffset_[l]);
      toBf16Rows(n, evenUp(W), g, S, k.rows.data(), S);
      productBf16(Bf16Epilogue::Mask, n, evenUp(W), k.rows.data(), S, backwardBf16_[l].data(), S, hidden(l - 1), g2);
    } else {
      accumulateOuter(n, W, g, S, hidden(l - 1), S, dW + gradOffset_[l]);
      productMasked(n, W, g, S, backward_[l].data(), S, hidden(l - 1), g2);
    }
    std::swap(g, g2);
  }
  // Layer 0: per tile (sum of its rows) for the latent part, per row for the directions.
  sumTileGradients(n, W, S, r0, rowsPerTile, sums.firstTile, g, sums.tileGrad.data());
  accumulateOuter(n, D, k.inputs.data(), D + 1, g, S, sums.dirGrad.data());
  if (trailingInputs_ > 0) {
    // dLoss/d(input) of the last P inputs: g [n x W] times those P columns of W_d.
    const int P = trailingInputs_, padded = paddedWidth(P);
    k.inputGrad.resize(static_cast<std::size_t>(kChunkRows) * padded);
    product(n, W, g, S, trailingWeights_.data(), padded, k.inputGrad.data());
    float* out = inputGradient_.data() + static_cast<std::size_t>(r0) * P;
    for (int r = 0; r < n; ++r) std::copy_n(k.inputGrad.data() + static_cast<std::size_t>(r) * padded, P, out + r * P);
  }
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
  // Layer 0's right-hand side: W_d^T padded to the stride, and a last row (the tile's
  // W_z z + b, set per chunk) whose column W is 1.
  layer0_.assign(static_cast<std::size_t>(D + 1) * S, 0.0f);
  const float* w0p = w0.data_ptr<float>();
  const auto w0At = [&](int j, int q) { return w0p[static_cast<std::size_t>(j) * (latentDim_ + D) + latentDim_ + q]; };
  for (int q = 0; q < D; ++q)
    for (int j = 0; j < W; ++j) layer0_[static_cast<std::size_t>(q) * S + j] = w0At(j, q);
  layer0_[static_cast<std::size_t>(D) * S + W] = 1.0f;
  const int padded = paddedWidth(std::max(trailingInputs_, 1));
  trailingWeights_.assign(static_cast<std::size_t>(W) * padded, 0.0f);
  for (int j = 0; j < W; ++j)
    for (int p = 0; p < trailingInputs_; ++p)
      trailingWeights_[static_cast<std::size_t>(j) * padded + p] = w0At(j, D - trailingInputs_ + p);
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
    if (bf16_ && targets) {
      forwardBf16_.resize(L);
      backwardBf16_.resize(L);
      forwardBf16_[l].assign(static_cast<std::size_t>(evenUp(W + 1)) * S, 0);
      backwardBf16_[l].assign(static_cast<std::size_t>(evenUp(out)) * S, 0);
      toBf16RowPairs(W + 1, S, f.data(), S, forwardBf16_[l].data());
      toBf16RowPairs(out, S, b.data(), S, backwardBf16_[l].data());
    }
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
  std::vector<float> dirGrad(static_cast<std::size_t>(D) * S, 0.0f), tileGradSum(static_cast<std::size_t>(tiles) * W, 0.0f);
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
    for (int q = 0; q < D; ++q) g0[static_cast<std::size_t>(j) * (latentDim_ + D) + latentDim_ + q] = dirGrad[q * S + j];
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
