// Training the asymmetric encoder/decoder of the clustered neural BTF (sections 2.2-2.4,
// 3.1). Torch lives in the .cpp files of this folder only; this header is torch-free.
#pragma once
#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "io/btf_stack.h"
#include "codec/mlp.h"
#include "model/config/train_config.h"
#include "preprocess/abrdf_matrix.h"
#include "util/direction_planes.h"
#include "util/directions.h"

namespace nbtf {

// What training needs. In the clustered mode the encoder sees one representative per
// cluster; in the per-texel mode (ids empty) it sees every texel's own ABRDF.
struct TrainInputs {
  const BtfStack* stack = nullptr;      // targets: linear values / alpha
  float alpha = 1;                      // eq. (5)
  const MatrixXfCol* encoderInputs = nullptr;  // rows: representatives (k x D) or texels (M x D), standardized
  std::vector<std::int32_t> ids;        // M: texel -> row of encoderInputs; empty = identity (per-texel)
  // Per-texel modulation (clustered only): M x terms coefficients, orthonormal per cluster
  // (codec/texel_modulation.h); texel t's model value is sum_r e_tr f_r(z_c, l, v), the
  // decoder giving 3 x terms outputs (model.outputTerms = terms). Empty = none (every texel of
  // a cluster has the same value).
  // With coefficientChannels 3: M x terms x 3 (term r, channel c at 3 r + c), channel c's
  // value mixing only its own.
  std::vector<float> texelCoefficients;
  int coefficientTerms = 0;
  int coefficientChannels = 1;
};

struct TrainResult {
  Mlp decoder;                          // input latent + the direction inputs (ModelConfig::directionInputCount)
  DirectionPlanes planes;               // the learned direction planes; empty without
  RowPlanes clusterPlanes;              // each latent row's own planes; empty without
  std::vector<float> latents;           // rows x latentDim
  int latentRows = 0;
  std::vector<std::uint8_t> encoderState;  // serialized encoder (for --save-encoder)
  std::vector<int> holdoutImages;       // image indices kept out of training
  double rmseTrain = 0;                 // eq. (10) on linear values / alpha, training images
  double rmseHoldout = -1;              // same on held-out images; -1 when none
  // Clustered: the floor, the RMSE of the best one-latent-per-cluster model (the cluster
  // means, with the per-texel factors when given) on the training images; -1 per-texel.
  double rmseFloor = -1;
  // Modulated: the floor of the plain cluster means (without the per-texel factors); -1 else.
  double rmsePlainFloor = -1;
  double seconds = 0;                   // whole call: setup, training, evaluation
  double trainSeconds = 0;              // the optimization loop only
  int epochsRun = 0;                    // completed epochs
  std::int64_t steps = 0;               // optimizer steps done (including resumed ones)
  std::int64_t resumedFromStep = 0;     // 0 = fresh start
  bool interrupted = false;             // stopped early (stopFlag / stopAtStep); rmse* are then -1
  double samplesPerSecond = 0;          // decoder samples (forward + backward) per second of the loop
  double decoderGflops = 0;             // samplesPerSecond x 3 x forward flops of the decoder
  std::string products = "float";       // the products training ran with: "float" | "bf16" ("auto" resolved)
  double finalLoss = 0;                 // smoothed training loss at the end (MSE vs cluster means)
  int encoderBlocks = 0;                // conv blocks used for this N
  // Data-parallel runs: this rank is not rank 0 (it trained its shares; rank 0 exports and
  // evaluates, so decoder, latents and rmse* are empty / -1 here), and the gradient traffic.
  bool worker = false;
  double allReduceBytesPerStep = 0, allReduceSecondsPerStep = 0;
  // Where the loop's time went (seconds): drawing samples and gathering targets, encoder
  // forward + backward, the decoder's forward + backward (with the planes' gradients), the
  // optimizer update (with the all-reduce when data-parallel).
  struct Profile {
    double sampling = 0, encoder = 0, decoder = 0, optimizer = 0;
    double steps() const { return sampling + encoder + decoder + optimizer; }
  } profile;
};

TrainResult trainModel(const TrainInputs& inputs, const TrainConfig& config);

// The tensors of a training checkpoint by name ("encoder/...", "decoder/...",
// "optimizer/..." for Adam's moments and step counts), flattened to doubles, with its step:
// for tests and tools that compare states bit for bit, without torch in their headers.
struct CheckpointState {
  std::int64_t step = 0;
  std::uint64_t fingerprint = 0;
  std::vector<std::pair<std::string, std::vector<double>>> tensors;  // in archive key order
};
CheckpointState readCheckpointState(const std::string& path);

// How far the run that wrote a checkpoint got, read without loading the model: the header,
// checksum and version are checked, so a damaged or foreign file is refused (nbtf::Error naming
// it) before the stack it belongs to is loaded.
struct CheckpointSummary {
  std::int64_t step = 0;
  std::int64_t totalSteps = 0;  // the run's planned steps (0: a time budget only)
  double elapsedSeconds = 0;    // training time so far
};
CheckpointSummary readCheckpointSummary(const std::string& path);

}  // namespace nbtf
