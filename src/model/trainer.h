// Training the asymmetric encoder/decoder of the clustered neural BTF (sections 2.2-2.4,
// 3.1). Torch lives in the .cpp files of this folder only; this header is torch-free.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "io/btf_stack.h"
#include "model/mlp.h"
#include "preprocess/abrdf_matrix.h"

namespace nbtf {

// Network shape. Defaults are the paper's (8-dim latent, 4 linear decoder layers of 106).
struct ModelConfig {
  int latentDim = 8;
  std::vector<int> encoderChannels = {16, 32, 64};  // one conv block per entry
  int decoderWidth = 106;
  int decoderLayers = 4;  // linear layers, ReLU between, linear RGB output
};

// The training recipe (configs/*.json, one object per component).
struct TrainConfig {
  ModelConfig model;
  std::string optimizer = "adam";  // "sgd" | "adam"
  double learningRate = 1e-3;
  double momentum = 0;             // sgd only
  int batchSize = 4096;            // decoder samples per step
  int epochs = 20;
  double timeBudgetSeconds = 0;    // 0 = no limit; stops after the epoch that passes it
  std::string schedule = "cosine"; // "constant" | "cosine" | "step"
  double holdoutFraction = 0;      // fraction of (light, view) images kept out of training
  std::uint64_t seed = 1;
  int threads = 0;                 // 0 = all cores
  double checkpointSeconds = 300;  // checkpoint interval (0 = never)
  std::string checkpointPath;      // "" = no checkpoints
  bool resume = false;             // continue from checkpointPath if present
  bool progress = true;
};

// Loads a config file; unknown keys and wrong types are errors naming the file and key.
TrainConfig loadTrainConfig(const std::string& path);

// What training needs. In the clustered mode the encoder sees one representative per
// cluster; in the per-texel mode (ids empty) it sees every texel's own ABRDF.
struct TrainInputs {
  const BtfStack* stack = nullptr;      // targets: linear values / alpha
  float alpha = 1;                      // eq. (5)
  const MatrixXfCol* encoderInputs = nullptr;  // rows: representatives (k x D) or texels (M x D), standardized
  std::vector<std::int32_t> ids;        // M: texel -> row of encoderInputs; empty = identity (per-texel)
};

struct TrainResult {
  Mlp decoder;                          // input latent + 2 + 2 (stereographic light, view)
  std::vector<float> latents;           // rows x latentDim
  int latentRows = 0;
  std::vector<std::uint8_t> encoderState;  // serialized encoder (for --save-encoder)
  std::vector<int> holdoutImages;       // image indices kept out of training
  double rmseTrain = 0;                 // eq. (10) on linear values / alpha, training images
  double rmseHoldout = -1;              // same on held-out images; -1 when none
  double seconds = 0;
  int epochsRun = 0;
  double samplesPerSecond = 0;          // decoder samples (forward + backward)
};

TrainResult trainModel(const TrainInputs& inputs, const TrainConfig& config);

}  // namespace nbtf
