// Training checkpoints: model, optimizer state and position, written atomically (temp
// file + rename) so an interrupted write never replaces a good checkpoint with a broken
// one. PRIVATE to src/model/ (includes torch).
#pragma once
#include <cstdint>
#include <memory>
#include <string>

#include "model/autograd/torch_modules.h"
#include "model/training_set.h"

namespace nbtf {

// The latents the decoder fits once the encoder is frozen (the polish phase): the encoder's
// outputs and, with optimizer.latent_learning_rate > 0, free parameters from then on, moved by
// their own Adam (Zeltner et al. 2024 bootstrap latents with an encoder, then fine-tune them).
// `values` is undefined before the polish phase.
struct PolishLatents {
  torch::Tensor values;                           // [encoder inputs, latent], on the CPU
  std::unique_ptr<torch::optim::Adam> optimizer;  // null: the latents stay the encoder's
  // Begins the phase with `latents`; learningRate 0 keeps them fixed.
  void start(torch::Tensor latents, double learningRate);
  bool free() const { return optimizer != nullptr; }
};

struct CheckpointMeta {
  std::int64_t step = 0;
  double elapsedSeconds = 0;  // training time so far, for time budgets across resumes
  double emaLoss = -1;
  std::uint64_t fingerprint = 0;
  // The run's planned optimizer steps (0: bounded by a time budget only). The learning-rate
  // schedule spans them, so a resumed run must plan the same.
  std::int64_t totalSteps = 0;
};

// What must match for a checkpoint to be resumable: model shape, optimizer, data shape,
// hold-out split and step geometry. (Epochs, learning rate and time budget may change.)
std::uint64_t checkpointFingerprint(const TrainConfig& config, const TrainingSet& set);

bool checkpointExists(const std::string& path);
// Free polish latents (PolishLatents::free) are saved with their optimizer state.
void saveCheckpoint(const std::string& path, const CheckpointMeta& meta, torch::nn::Module& encoder,
                    torch::nn::Module& decoder, torch::optim::Optimizer& optimizer, const PolishLatents& polish);
// Throws nbtf::Error naming the path if the file is unreadable or from another setup.
// checkFingerprint = false: a warm start across a change of the clusters (TrainConfig::warmStart);
// saved polish latents are then not loaded (they belong to the old clusters). Otherwise saved
// free latents restart `polish` with latentLearningRate and their optimizer state.
CheckpointMeta loadCheckpoint(const std::string& path, std::uint64_t expectedFingerprint, torch::nn::Module& encoder,
                              torch::nn::Module& decoder, torch::optim::Optimizer& optimizer, PolishLatents& polish,
                              double latentLearningRate, bool checkFingerprint = true);

}  // namespace nbtf
