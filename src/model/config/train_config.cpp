// Training configs: JSON, one object per component. Every key is optional (defaults are
// TrainConfig's); unknown keys, wrong types and out-of-range values are errors that name
// the file and the key, so a typo never silently trains with a default.
#include <algorithm>
#include <climits>
#include <cmath>
#include <nlohmann/json.hpp>
#include <type_traits>
#include <variant>

#include "model/config/config_section.h"
#include "model/config/train_config.h"
#include "util/error.h"

namespace nbtf {
namespace {

[[noreturn]] void bad(const std::string& source, const std::string& key, const std::string& msg) {
  throw fileError(source, "'" + key + "' " + msg);
}

}  // namespace

TrainConfig loadTrainConfig(const std::string& path) {
  std::vector<std::string> sections = kTrainConfigSections;
  sections.insert(sections.end(), kCompressOnlyConfigSections.begin(), kCompressOnlyConfigSections.end());
  return trainConfigFromJson(readConfigFile(path, sections), path);
}

namespace {

// One entry per config key (config_section.h): the reader and the writer both walk this table.
// Keys added after format 1.0 are recorded only when they differ from what older files imply,
// so those files keep their bytes; run settings (checkpoints, progress) do not change the
// result and are never recorded.
using ConfigField = nbtf::ConfigField<TrainConfig>;

bool never(const TrainConfig&) { return false; }
bool withPlanes(const TrainConfig& c) { return c.model.planeFeatures > 0; }
bool withClusterPlanes(const TrainConfig& c) { return c.model.clusterPlaneFeatures > 0; }
bool withModulation(const TrainConfig& c) { return c.modulation.mode != "none"; }
bool withLatentBlur(const TrainConfig& c) { return c.latentBlurSigma > 0; }

#define NBTF_CONFIG_FIELD(section, key, member, recorded) \
  ConfigField { section, key, [](TrainConfig& c) -> ConfigValue { return &c.member; }, recorded }

const ConfigField kConfigFields[] = {
    NBTF_CONFIG_FIELD("model", "latent_dim", model.latentDim, nullptr),
    NBTF_CONFIG_FIELD("model", "encoder_channels", model.encoderChannels, nullptr),
    NBTF_CONFIG_FIELD("model", "decoder_width", model.decoderWidth, nullptr),
    NBTF_CONFIG_FIELD("model", "decoder_layers", model.decoderLayers, nullptr),
    // Always recorded: an absent key reads as today's default, not as what ran.
    NBTF_CONFIG_FIELD("model", "direction_inputs", model.directionInputs, nullptr),
    NBTF_CONFIG_FIELD("direction_planes", "resolution", model.planeResolution, withPlanes),
    NBTF_CONFIG_FIELD("direction_planes", "features", model.planeFeatures, withPlanes),
    NBTF_CONFIG_FIELD("cluster_planes", "resolution", model.clusterPlaneResolution, withClusterPlanes),
    NBTF_CONFIG_FIELD("cluster_planes", "features", model.clusterPlaneFeatures, withClusterPlanes),
    NBTF_CONFIG_FIELD("optimizer", "name", optimizer, nullptr),
    NBTF_CONFIG_FIELD("optimizer", "learning_rate", learningRate, nullptr),
    NBTF_CONFIG_FIELD("optimizer", "learning_rate_scaling", learningRateScaling, nullptr),
    NBTF_CONFIG_FIELD("optimizer", "momentum", momentum, nullptr),
    // Always recorded: an absent key reads as today's default (0.01), not as what ran.
    NBTF_CONFIG_FIELD("optimizer", "latent_learning_rate", latentLearningRate, nullptr),
    NBTF_CONFIG_FIELD("optimizer", "plane_learning_rate", planeLearningRate, withPlanes),
    NBTF_CONFIG_FIELD("training", "batch_size", batchSize, nullptr),
    NBTF_CONFIG_FIELD("training", "images_per_input", imagesPerInput, nullptr),
    NBTF_CONFIG_FIELD("training", "epochs", epochs, nullptr),
    NBTF_CONFIG_FIELD("training", "min_steps", minSteps, nullptr),
    NBTF_CONFIG_FIELD("training", "min_steps_per_input", minStepsPerInput, nullptr),
    NBTF_CONFIG_FIELD("training", "max_steps", maxSteps, nullptr),
    NBTF_CONFIG_FIELD("training", "time_budget_seconds", timeBudgetSeconds, nullptr),
    NBTF_CONFIG_FIELD("training", "schedule", schedule, nullptr),
    NBTF_CONFIG_FIELD("training", "warmup_fraction", warmupFraction, nullptr),
    NBTF_CONFIG_FIELD("training", "polish_fraction", polishFraction, nullptr),
    NBTF_CONFIG_FIELD("training", "latent_blur_sigma", latentBlurSigma, withLatentBlur),
    NBTF_CONFIG_FIELD("training", "latent_blur_half_life", latentBlurHalfLife, withLatentBlur),
    NBTF_CONFIG_FIELD("training", "holdout_fraction", holdoutFraction, nullptr),
    NBTF_CONFIG_FIELD("training", "seed", seed, nullptr),
    NBTF_CONFIG_FIELD("training", "threads", threads, nullptr),
    NBTF_CONFIG_FIELD("training", "checkpoint_seconds", checkpointSeconds, never),
    NBTF_CONFIG_FIELD("training", "checkpoint_path", checkpointPath, never),
    NBTF_CONFIG_FIELD("training", "resume", resume, never),
    NBTF_CONFIG_FIELD("training", "progress", progress, never),
    // The backends' numerics differ in the last bits: recorded when not the default.
    NBTF_CONFIG_FIELD("training", "backend", backend, [](const TrainConfig& c) { return c.backend != "fused"; }),
    NBTF_CONFIG_FIELD("training", "products", products, [](const TrainConfig& c) { return c.products != "auto"; }),
    NBTF_CONFIG_FIELD("training", "device", device, [](const TrainConfig& c) { return c.device != "cpu"; }),
    NBTF_CONFIG_FIELD("modulation", "mode", modulation.mode, nullptr),
    NBTF_CONFIG_FIELD("modulation", "terms", modulation.terms, nullptr),
    NBTF_CONFIG_FIELD("modulation", "bits", modulation.bits, nullptr),
    NBTF_CONFIG_FIELD("modulation", "channels", modulation.channels, withModulation),
    NBTF_CONFIG_FIELD("modulation", "mean_weight", modulation.meanWeight, withModulation),
    NBTF_CONFIG_FIELD("modulation", "codes", modulation.codes, withModulation),
    NBTF_CONFIG_FIELD("storage", "decoder", storage.decoder, nullptr),
    NBTF_CONFIG_FIELD("storage", "latents", storage.latents, nullptr),
    NBTF_CONFIG_FIELD("storage", "ids", storage.ids, nullptr),
    NBTF_CONFIG_FIELD("storage", "directions", storage.directions, nullptr),
    NBTF_CONFIG_FIELD("storage", "metadata", storage.metadata, nullptr),
    NBTF_CONFIG_FIELD("storage", "cluster_planes", storage.clusterPlanes,
                      [](const TrainConfig& c) { return withClusterPlanes(c) && c.storage.clusterPlanes != "auto"; }),
};

#undef NBTF_CONFIG_FIELD

}  // namespace

TrainConfig trainConfigFromJson(const nlohmann::json& root, const std::string& path) {
  TrainConfig c;
  for (const std::string& name : kTrainConfigSections) {
    ConfigSection section(root, name, path);
    readConfigFields(section, name, kConfigFields, c, path);
    section.rejectUnknown();
  }
  validateTrainConfig(c, path);
  return c;
}

std::string trainConfigJson(const TrainConfig& config) { return configFieldsJson(kConfigFields, config).dump(); }

namespace {

void validateModel(const TrainConfig& c, const std::string& source) {
  if (c.model.latentDim < 1 || c.model.latentDim > 4096) bad(source, "model.latent_dim", "must be in 1..4096");
  for (int ch : c.model.encoderChannels)
    if (ch < 1 || ch > 4096) bad(source, "model.encoder_channels", "entries must be in 1..4096");
  if (c.model.decoderWidth < 1 || c.model.decoderWidth > 65536) bad(source, "model.decoder_width", "must be in 1..65536");
  if (c.model.decoderLayers < 2 || c.model.decoderLayers > 64)
    bad(source, "model.decoder_layers", "must be in 2..64 (input and output layers at least)");
  if (c.model.planeFeatures < 0 || c.model.planeFeatures > DirectionPlanes::kMaxFeatures)
    bad(source, "direction_planes.features",
        "must be in 0.." + std::to_string(DirectionPlanes::kMaxFeatures) + " (0: no direction planes)");
  if (c.model.planeResolution < 2 || c.model.planeResolution > DirectionPlanes::kMaxResolution)
    bad(source, "direction_planes.resolution", "must be in 2.." + std::to_string(DirectionPlanes::kMaxResolution));
  if (c.model.clusterPlaneFeatures < 0 || c.model.clusterPlaneFeatures > DirectionPlanes::kMaxFeatures)
    bad(source, "cluster_planes.features",
        "must be in 0.." + std::to_string(DirectionPlanes::kMaxFeatures) + " (0: no cluster planes)");
  if (c.model.clusterPlaneResolution < 2 || c.model.clusterPlaneResolution > DirectionPlanes::kMaxResolution)
    bad(source, "cluster_planes.resolution", "must be in 2.." + std::to_string(DirectionPlanes::kMaxResolution));
}

void validateOptimizer(const TrainConfig& c, const std::string& source) {
  if (c.optimizer != "sgd" && c.optimizer != "adam")
    bad(source, "optimizer.name", "must be \"sgd\" or \"adam\", got \"" + c.optimizer + "\"");
  if (!std::isfinite(c.learningRate) || c.learningRate <= 0) bad(source, "optimizer.learning_rate", "must be > 0");
  if (c.learningRateScaling != "inputs" && c.learningRateScaling != "none")
    bad(source, "optimizer.learning_rate_scaling",
        "must be \"inputs\" or \"none\", got \"" + c.learningRateScaling + "\"");
  if (!std::isfinite(c.momentum) || c.momentum < 0 || c.momentum >= 1)
    bad(source, "optimizer.momentum", "must be in [0, 1)");
  if (!std::isfinite(c.latentLearningRate) || c.latentLearningRate < 0)
    bad(source, "optimizer.latent_learning_rate", "must be >= 0 (0: the latents stay the encoder's outputs)");
  if (c.latentLearningRate > 0 && c.polishFraction > 0 && c.optimizer != "adam")
    bad(source, "optimizer.latent_learning_rate", "needs optimizer.name \"adam\" (or 0: latents fixed in the polish phase)");
  if (!std::isfinite(c.planeLearningRate) || c.planeLearningRate < 0)
    bad(source, "optimizer.plane_learning_rate", "must be >= 0 (0: optimizer.learning_rate)");
}

void validateTraining(const TrainConfig& c, const std::string& source) {
  if (c.batchSize < 1) bad(source, "training.batch_size", "must be >= 1");
  if (c.backend != "fused" && c.backend != "torch")
    bad(source, "training.backend", "must be \"fused\" or \"torch\", got \"" + c.backend + "\"");
  if (c.products != "float" && c.products != "bf16" && c.products != "auto")
    bad(source, "training.products", "must be \"float\", \"bf16\" or \"auto\", got \"" + c.products + "\"");
  if (c.products == "bf16" && c.backend != "fused")
    bad(source, "training.products", "\"bf16\" needs training.backend \"fused\" (its kernels are the fused pass's)");
  if (c.device != "cpu" && c.device != "cuda")
    bad(source, "training.device", "must be \"cpu\" or \"cuda\", got \"" + c.device + "\"");
  if (c.device == "cuda" && c.backend != "torch")
    bad(source, "training.device", "\"cuda\" needs training.backend \"torch\" (the fused kernels are CPU code)");
  if (c.imagesPerInput < 1) bad(source, "training.images_per_input", "must be >= 1");
  if (c.epochs < 0) bad(source, "training.epochs", "must be >= 0");
  if (!std::isfinite(c.timeBudgetSeconds) || c.timeBudgetSeconds < 0)
    bad(source, "training.time_budget_seconds", "must be >= 0 (0 = no limit)");
  if (c.minSteps < 0) bad(source, "training.min_steps", "must be >= 0 (0 = no minimum)");
  if (c.minStepsPerInput < 0)
    bad(source, "training.min_steps_per_input", "must be >= 0 (0 = no minimum per encoder input)");
  if (c.maxSteps < 0) bad(source, "training.max_steps", "must be >= 0 (0 = no maximum)");
  if (c.minSteps > 0 && c.maxSteps > 0 && c.minSteps > c.maxSteps)
    bad(source, "training.min_steps", "(" + std::to_string(c.minSteps) + ") must not exceed training.max_steps (" +
                                          std::to_string(c.maxSteps) + ")");
  if (c.epochs == 0 && c.timeBudgetSeconds == 0)
    bad(source, "training.epochs", "is 0 and there is no time budget: nothing would be trained");
  if (c.schedule != "constant" && c.schedule != "cosine" && c.schedule != "step")
    bad(source, "training.schedule", "must be \"constant\", \"cosine\" or \"step\", got \"" + c.schedule + "\"");
  if (!std::isfinite(c.warmupFraction) || c.warmupFraction < 0 || c.warmupFraction >= 1)
    bad(source, "training.warmup_fraction", "must be in [0, 1)");
  if (!std::isfinite(c.polishFraction) || c.polishFraction < 0 || c.polishFraction >= 1)
    bad(source, "training.polish_fraction", "must be in [0, 1)");
  if (c.warmupFraction + c.polishFraction >= 1)
    bad(source, "training.polish_fraction", "plus warmup_fraction must be < 1");
  if (!std::isfinite(c.latentBlurSigma) || c.latentBlurSigma < 0 || c.latentBlurSigma > 64)
    bad(source, "training.latent_blur_sigma", "must be in [0, 64] texels (0 = no blur)");
  if (!std::isfinite(c.latentBlurHalfLife) || c.latentBlurHalfLife <= 0)
    bad(source, "training.latent_blur_half_life", "must be > 0 (a fraction of the polish phase)");
  if (!std::isfinite(c.holdoutFraction) || c.holdoutFraction < 0 || c.holdoutFraction >= 1)
    bad(source, "training.holdout_fraction", "must be in [0, 1)");
  if (c.threads < 0) bad(source, "training.threads", "must be >= 0 (0 = all cores)");
  if (!std::isfinite(c.checkpointSeconds) || c.checkpointSeconds < 0)
    bad(source, "training.checkpoint_seconds", "must be >= 0 (0 = only when stopped)");
  if (c.resume && c.checkpointPath.empty()) bad(source, "training.resume", "needs training.checkpoint_path");
}

void validateModulation(const TrainConfig& c, const std::string& source) {
  const ModulationConfig& m = c.modulation;
  if (m.mode != "none" && m.mode != "svd")
    bad(source, "modulation.mode", "must be \"none\" or \"svd\", got \"" + m.mode + "\"");
  if (m.terms < 1 || m.terms > 8) bad(source, "modulation.terms", "must be in 1..8");
  if (m.bits < 1 || m.bits > 16) bad(source, "modulation.bits", "must be in 1..16");
  if (m.channels != 1 && m.channels != 3)
    bad(source, "modulation.channels", "must be 1 (one coefficient for RGB) or 3 (one per channel), got " +
                                           std::to_string(m.channels));
  if (m.codes != "linear" && m.codes != "decorrelated")
    bad(source, "modulation.codes", "must be \"linear\" or \"decorrelated\", got \"" + m.codes + "\"");
  if (!std::isfinite(m.meanWeight) || m.meanWeight < 0)
    bad(source, "modulation.mean_weight", "must be a number >= 0 (0 = plain least squares)");
}

void validateStorage(const TrainConfig& c, const std::string& source) {
  if (c.storage.decoder != "float32" && c.storage.decoder != "half" && c.storage.decoder != "int8")
    bad(source, "storage.decoder", "must be \"float32\", \"half\" or \"int8\", got \"" + c.storage.decoder + "\"");
  if (c.storage.latents != "float32" && c.storage.latents != "half")
    bad(source, "storage.latents", "must be \"float32\" or \"half\", got \"" + c.storage.latents + "\"");
  if (c.storage.ids != "raw" && c.storage.ids != "zstd")
    bad(source, "storage.ids", "must be \"raw\" or \"zstd\", got \"" + c.storage.ids + "\"");
  if (c.storage.directions != "f64" && c.storage.directions != "zstd")
    bad(source, "storage.directions", "must be \"f64\" or \"zstd\", got \"" + c.storage.directions + "\"");
  if (c.storage.clusterPlanes != "auto" && c.storage.clusterPlanes != "8bit")
    bad(source, "storage.cluster_planes", "must be \"auto\" (as the direction planes) or \"8bit\", got \"" +
                                              c.storage.clusterPlanes + "\"");
  if (c.storage.metadata != "raw" && c.storage.metadata != "zstd")
    bad(source, "storage.metadata", "must be \"raw\" or \"zstd\", got \"" + c.storage.metadata + "\"");
}

}  // namespace

void validateTrainConfig(const TrainConfig& c, const std::string& source) {
  validateModel(c, source);
  validateOptimizer(c, source);
  validateTraining(c, source);
  validateModulation(c, source);
  validateStorage(c, source);
}

TrainPlan planTraining(const TrainConfig& c, std::int64_t encoderInputs, int trainImages) {
  if (encoderInputs < 1 || trainImages < 1) throw Error("planTraining: no encoder inputs or no training images");
  TrainPlan p;
  p.perTile = std::min(c.imagesPerInput, trainImages);
  p.tiles = std::max(1, c.batchSize / p.perTile);
  p.batch = static_cast<std::int64_t>(p.tiles) * p.perTile;
  const double samplesPerEpoch = static_cast<double>(encoderInputs) * trainImages;
  p.stepsPerEpoch = std::max<std::int64_t>(1, std::llround(std::ceil(samplesPerEpoch / p.batch)));
  if (c.learningRateScaling == "inputs")
    p.learningRateScale = std::clamp(std::sqrt(p.tiles / kReferenceInputsPerStep), 1.0, kMaxLearningRateScale);
  if (c.epochs <= 0) return p;  // bounded by the time budget only
  p.totalSteps = p.stepsPerEpoch * c.epochs;
  // At least min_steps, and min_steps_per_input per encoder input (k, or texels per-texel):
  // the steps a decoder needs grow with the latents it fits. max_steps bounds both.
  p.totalSteps = std::max<std::int64_t>({p.totalSteps, c.minSteps, c.minStepsPerInput * encoderInputs});
  if (c.maxSteps > 0) p.totalSteps = std::min<std::int64_t>(p.totalSteps, c.maxSteps);
  return p;
}

}  // namespace nbtf
