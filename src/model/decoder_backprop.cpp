#include "model/decoder_backprop.h"

namespace nbtf::detail {

DecoderBackprop::DecoderBackprop(Decoder decoder, int latentDim)
    : decoder_(std::move(decoder)), latentDim_(latentDim) {
  layers_ = static_cast<int>(decoder_->layers.size());
  width_ = static_cast<int>(decoder_->layers[0]->weight.size(0));
  for (auto& lin : decoder_->layers) {
    weightGrad_.push_back(torch::zeros_like(lin->weight));
    biasGrad_.push_back(torch::zeros_like(lin->bias));
  }
}

void DecoderBackprop::ensureBuffers(std::int64_t rows) {
  if (out_.defined() && out_.size(0) == rows) return;
  hidden_.assign(layers_ - 1, torch::Tensor());
  for (auto& h : hidden_) h = torch::empty({rows, width_});
  out_ = torch::empty({rows, 3});
  diff_ = torch::empty({rows, 3});
  grad_[0] = torch::empty({rows, width_});
  grad_[1] = torch::empty({rows, width_});
}

torch::Tensor DecoderBackprop::forward(const torch::Tensor& z, const torch::Tensor& dirs, int rowsPerTile) {
  torch::NoGradGuard noGrad;
  const std::int64_t tiles = z.size(0), rows = dirs.size(0);
  TORCH_CHECK(rows == tiles * rowsPerTile, "decoder: rows must be tiles x rowsPerTile");
  ensureBuffers(rows);
  const auto& first = decoder_->layers[0];
  torch::Tensor wz = first->weight.narrow(1, 0, latentDim_), wd = first->weight.narrow(1, latentDim_, 4);
  // Layer 0: relu(W_d d + (W_z z + b)), the latent part once per tile, broadcast over its rows.
  torch::Tensor perTile = torch::addmm(first->bias, z, wz.t());
  torch::mm_out(hidden_[0], dirs, wd.t());
  hidden_[0].view({tiles, rowsPerTile, width_}).add_(perTile.unsqueeze(1));
  hidden_[0].relu_();
  for (int l = 1; l + 1 < layers_; ++l) {
    const auto& lin = decoder_->layers[l];
    torch::addmm_out(hidden_[l], lin->bias, hidden_[l - 1], lin->weight.t());
    hidden_[l].relu_();
  }
  const auto& last = decoder_->layers[layers_ - 1];
  torch::addmm_out(out_, last->bias, hidden_[layers_ - 2], last->weight.t());
  return out_;
}

double DecoderBackprop::trainStep(const torch::Tensor& z, const torch::Tensor& dirs, const torch::Tensor& targets,
                                  int rowsPerTile, torch::Tensor& dz) {
  forward(z, dirs, rowsPerTile);
  torch::NoGradGuard noGrad;
  const std::int64_t tiles = z.size(0), rows = dirs.size(0);
  // Loss = mean over rows x 3 of (out - target)^2; dLoss/dout = 2 (out - target) / (3 rows).
  torch::sub_out(diff_, out_, targets);
  double loss = diff_.square().sum().item<double>() / (3.0 * rows);
  diff_.mul_(2.0 / (3.0 * rows));

  // Output layer.
  const int L = layers_;
  torch::mm_out(weightGrad_[L - 1], diff_.t(), hidden_[L - 2]);
  torch::sum_out(biasGrad_[L - 1], diff_, {0});
  torch::Tensor g = grad_[0], gNext = grad_[1];
  torch::mm_out(g, diff_, decoder_->layers[L - 1]->weight);
  // Hidden layers, top down: mask by the ReLU, then weight gradient, bias gradient, and the
  // gradient for the layer below.
  for (int l = L - 2; l >= 1; --l) {
    torch::threshold_backward_out(g, g, hidden_[l], 0);
    torch::mm_out(weightGrad_[l], g.t(), hidden_[l - 1]);
    torch::sum_out(biasGrad_[l], g, {0});
    torch::mm_out(gNext, g, decoder_->layers[l]->weight);
    std::swap(g, gNext);
  }
  // First layer: the latent part per tile (sum over its rows), the direction part per row.
  torch::threshold_backward_out(g, g, hidden_[0], 0);
  torch::Tensor perTile = g.view({tiles, rowsPerTile, width_}).sum(1);  // [tiles, width]
  const auto& first = decoder_->layers[0];
  weightGrad_[0].narrow(1, latentDim_, 4).copy_(torch::mm(g.t(), dirs));
  weightGrad_[0].narrow(1, 0, latentDim_).copy_(torch::mm(perTile.t(), z));
  torch::sum_out(biasGrad_[0], perTile, {0});
  dz = torch::mm(perTile, first->weight.narrow(1, 0, latentDim_));

  for (int l = 0; l < L; ++l) {
    decoder_->layers[l]->weight.mutable_grad() = weightGrad_[l];
    decoder_->layers[l]->bias.mutable_grad() = biasGrad_[l];
  }
  return loss;
}

}  // namespace nbtf::detail
