// The training recipe (model/config/train_config.cpp): the config files' reader and checks, the
// shipped configs, and the step plan a recipe gives.
#include "model/config/train_config.h"

#include <gtest/gtest.h>

#include <cmath>

#include "model/config/config_section.h"
#include "test_util.h"

namespace nbtf {
namespace {

TEST(TrainPlan, LearningRateGrowsWithTheInputsAStepHolds) {
  TrainConfig c;
  EXPECT_EQ(c.learningRateScaling, "inputs");
  EXPECT_DOUBLE_EQ(planTraining(c, 500, 6561).learningRateScale, 1.0);   // 32 inputs x 512 images
  EXPECT_DOUBLE_EQ(planTraining(c, 500, 22801).learningRateScale, 1.0);
  EXPECT_DOUBLE_EQ(planTraining(c, 500, 81).learningRateScale, 2.5);     // 202 inputs: sqrt 2.51, capped
  const TrainPlan mid = planTraining(c, 500, 200);                        // 81 inputs x 200 images
  EXPECT_EQ(mid.tiles, 81);
  EXPECT_NEAR(mid.learningRateScale, std::sqrt(81.0 / 32.0), 1e-12);
  EXPECT_DOUBLE_EQ(planTraining(c, 500, 1).learningRateScale, 2.5);      // never more than measured
  c.learningRateScaling = "none";
  EXPECT_DOUBLE_EQ(planTraining(c, 500, 81).learningRateScale, 1.0);
  c.learningRateScaling = "inputs";
  c.epochs = 0;  // a time budget only: the same rate
  EXPECT_DOUBLE_EQ(planTraining(c, 500, 81).learningRateScale, 2.5);
}

TEST(TrainPlan, DefaultStepsAreBoundedWhateverKAndImages) {
  TrainConfig c;  // the defaults: 20 epochs, 2000 .. 12000 steps, 24 steps per input, 16384 samples per step
  EXPECT_EQ(c.minSteps, 2000);
  EXPECT_EQ(c.minStepsPerInput, 24);
  EXPECT_EQ(c.maxSteps, 12000);
  TrainPlan small = planTraining(c, 16, 81);  // k = 16, one view: an epoch is one step
  EXPECT_EQ(small.stepsPerEpoch, 1);
  EXPECT_EQ(small.totalSteps, 2000);                         // min_steps decides up to k = 83
  EXPECT_EQ(planTraining(c, 83, 81).totalSteps, 2000);
  EXPECT_EQ(planTraining(c, 84, 81).totalSteps, 24 * 84);    // then 24 steps per encoder input
  EXPECT_EQ(planTraining(c, 250, 81).totalSteps, 6000);
  TrainPlan sub = planTraining(c, 500, 81);                  // k = 500, 9 x 9 subset
  EXPECT_EQ(sub.stepsPerEpoch, 3);
  EXPECT_EQ(sub.totalSteps, 12000);                          // max_steps from k = 500 up
  EXPECT_EQ(planTraining(c, 1000, 81).totalSteps, 12000);    // the default k: no more than k = 500
  EXPECT_EQ(planTraining(c, 2000, 81).totalSteps, 12000);
  // k = 500 on a full stack: 20 epochs are 4,020 steps, the minimum per input 12,000.
  TrainPlan full = planTraining(c, 500, 6561);
  EXPECT_EQ(full.stepsPerEpoch, 201);
  EXPECT_EQ(full.totalSteps, 12000);
  EXPECT_EQ(planTraining(c, 1000, 6561).totalSteps, 12000);  // 24 per input = 24,000 steps, capped
  EXPECT_EQ(planTraining(c, 65536, 6561).totalSteps, c.maxSteps);  // per-texel 256 x 256
  // Epochs decide where they are more than the minimum, up to max_steps: k = 125 on 151 x 151
  // = 22,801 images (20 epochs: 3,480 steps against 24 x 125 = 3,000), k = 500 capped.
  TrainPlan dense = planTraining(c, 125, 22801);
  EXPECT_EQ(dense.stepsPerEpoch, 174);
  EXPECT_EQ(dense.totalSteps, 20 * 174);
  EXPECT_EQ(planTraining(c, 500, 22801).totalSteps, 12000);
  // configs/converged.json is 4x every bound.
  TrainConfig longer = c;
  longer.epochs = 4 * c.epochs, longer.minSteps = 4 * c.minSteps;
  longer.minStepsPerInput = 4 * c.minStepsPerInput, longer.maxSteps = 4 * c.maxSteps;
  for (std::int64_t k : {16, 32, 500, 2000})
    for (int images : {81, 6561})
      EXPECT_EQ(planTraining(longer, k, images).totalSteps, 4 * planTraining(c, k, images).totalSteps)
          << "k " << k << ", " << images << " images";
  TrainConfig exact = c;
  exact.minSteps = exact.minStepsPerInput = exact.maxSteps = 0;
  EXPECT_EQ(planTraining(exact, 16, 81).totalSteps, 20);
  EXPECT_EQ(planTraining(exact, 2000, 81).totalSteps, 20 * 10);
  TrainConfig budget = c;
  budget.epochs = 0, budget.timeBudgetSeconds = 10;
  EXPECT_EQ(planTraining(budget, 16, 81).totalSteps, 0);
  TrainConfig bad = c;
  bad.minSteps = 5, bad.maxSteps = 4;
  EXPECT_NE(test::errorOf([&] { validateTrainConfig(bad, "x.json"); }).find("'training.min_steps'"), std::string::npos);
  bad = c;
  bad.minStepsPerInput = -1;
  EXPECT_NE(test::errorOf([&] { validateTrainConfig(bad, "x.json"); }).find("'training.min_steps_per_input'"),
            std::string::npos);
}

TEST(TrainConfig, ShippedConfigsLoad) {
  TrainConfig def = loadTrainConfig(std::string(NBTF_SOURCE_DIR) + "/configs/default.json");
  EXPECT_EQ(def.model.latentDim, 8);
  EXPECT_EQ(def.model.decoderWidth, 106);
  EXPECT_EQ(def.model.decoderLayers, 4);
  TrainConfig paper = loadTrainConfig(std::string(NBTF_SOURCE_DIR) + "/configs/paper.json");
  EXPECT_EQ(paper.optimizer, "sgd");
  EXPECT_DOUBLE_EQ(paper.learningRate, 0.08);
  EXPECT_EQ(paper.batchSize, 5);
  EXPECT_EQ(paper.imagesPerInput, 1);
  EXPECT_EQ(paper.schedule, "constant");
  // converged.json is the default recipe run 4x as long (the convergence benchmark's recipe).
  TrainConfig converged = loadTrainConfig(std::string(NBTF_SOURCE_DIR) + "/configs/converged.json");
  EXPECT_EQ(converged.epochs, 4 * def.epochs);
  EXPECT_EQ(converged.minSteps, 4 * def.minSteps);
  EXPECT_EQ(converged.minStepsPerInput, 4 * def.minStepsPerInput);
  EXPECT_EQ(converged.maxSteps, 4 * def.maxSteps);
  EXPECT_EQ(converged.model.encoderChannels, def.model.encoderChannels);
  EXPECT_EQ(converged.optimizer, def.optimizer);
  EXPECT_DOUBLE_EQ(converged.learningRate, def.learningRate);
  EXPECT_EQ(converged.batchSize, def.batchSize);
  EXPECT_EQ(converged.imagesPerInput, def.imagesPerInput);
  EXPECT_EQ(converged.schedule, def.schedule);
  EXPECT_DOUBLE_EQ(converged.warmupFraction, def.warmupFraction);
  EXPECT_DOUBLE_EQ(converged.polishFraction, def.polishFraction);
}

TEST(TrainConfig, ReadsEveryComponent) {
  std::string path = test::writeTempText("full.json", R"({
    "model": {"latent_dim": 6, "encoder_channels": [4, 8], "decoder_width": 32, "decoder_layers": 3,
              "direction_inputs": "stereographic+half"},
    "direction_planes": {"resolution": 12, "features": 2},
    "optimizer": {"name": "adam", "learning_rate": 0.05, "latent_learning_rate": 0.01, "plane_learning_rate": 0.02},
    "training": {"batch_size": 512, "images_per_input": 16, "epochs": 7, "time_budget_seconds": 60,
                 "min_steps": 100, "min_steps_per_input": 3, "max_steps": 900, "schedule": "step", "warmup_fraction": 0, "polish_fraction": 0.2, "holdout_fraction": 0.1,
                 "seed": 9, "threads": 1, "checkpoint_seconds": 30, "checkpoint_path": "x.ckpt",
                 "resume": true, "progress": false},
    "modulation": {"mode": "svd", "terms": 2, "bits": 5, "mean_weight": 4, "channels": 3, "codes": "linear"}
  })");
  TrainConfig c = loadTrainConfig(path);
  EXPECT_EQ(c.model.latentDim, 6);
  EXPECT_EQ(c.model.encoderChannels, (std::vector<int>{4, 8}));
  EXPECT_EQ(c.model.decoderWidth, 32);
  EXPECT_EQ(c.model.decoderLayers, 3);
  EXPECT_EQ(c.model.directionInputs, DirectionEncoding::StereographicHalf);
  EXPECT_EQ(c.model.planeResolution, 12);
  EXPECT_EQ(c.model.planeFeatures, 2);
  EXPECT_EQ(decoderShape(c.model).inputSize(), 6 + 8 + 3 * 2);
  EXPECT_EQ(c.optimizer, "adam");
  EXPECT_DOUBLE_EQ(c.latentLearningRate, 0.01);
  EXPECT_DOUBLE_EQ(c.planeLearningRate, 0.02);
  EXPECT_EQ(c.batchSize, 512);
  EXPECT_EQ(c.imagesPerInput, 16);
  EXPECT_EQ(c.epochs, 7);
  EXPECT_EQ(c.minSteps, 100);
  EXPECT_EQ(c.minStepsPerInput, 3);
  EXPECT_EQ(c.maxSteps, 900);
  EXPECT_DOUBLE_EQ(c.timeBudgetSeconds, 60);
  EXPECT_EQ(c.schedule, "step");
  EXPECT_DOUBLE_EQ(c.polishFraction, 0.2);
  EXPECT_DOUBLE_EQ(c.holdoutFraction, 0.1);
  EXPECT_EQ(c.seed, 9u);
  EXPECT_EQ(c.threads, 1);
  EXPECT_EQ(c.checkpointPath, "x.ckpt");
  EXPECT_TRUE(c.resume);
  EXPECT_FALSE(c.progress);
  EXPECT_EQ(c.modulation.terms, 2);
  EXPECT_EQ(c.modulation.bits, 5);
  EXPECT_DOUBLE_EQ(c.modulation.meanWeight, 4);
  EXPECT_EQ(c.modulation.channels, 3);
  EXPECT_EQ(c.modulation.codes, "linear");  // the default is "decorrelated"
  std::filesystem::remove(path);
}

TEST(TrainConfig, ErrorsNameTheFileAndKey) {
  struct Case {
    const char* json;
    const char* expect;
  } cases[] = {
      {R"({"training": {"batch_sise": 64}})", "'training.batch_sise' unknown key"},
      {R"({"optimizer": {"learning_rate": "fast"}})", "'optimizer.learning_rate' must be a number, got a string"},
      {R"({"training": {"epochs": 2.5}})", "'training.epochs' must be an integer, got a number"},
      {R"({"model": {"encoder_channels": [8, "x"]}})", "'model.encoder_channels' must be an array of integers"},
      {R"({"training": {"progress": 1}})", "'training.progress' must be true or false"},
      {R"({"optimiser": {}})", "'optimiser' unknown key"},
      {R"({"model": 3})", "'model' must be an object"},
      {R"({"optimizer": {"name": "rmsprop"}})", "'optimizer.name' must be \"sgd\" or \"adam\""},
      {R"({"training": {"holdout_fraction": 1.5}})", "'training.holdout_fraction' must be in [0, 1)"},
      {R"({"training": {"seed": -1}})", "'training.seed' must be a non-negative integer"},
      {R"({"training": {"batch_size": 0}})", "'training.batch_size' must be >= 1"},
      {R"({"model": {"latent_dim": 8,}})", "not valid JSON"},
      {R"({"model": {"direction_inputs": "half"}})", "'model.direction_inputs' is not valid: unknown direction encoding \"half\""},
      {R"({"optimizer": {"learning_rate_scaling": "linear"}})",
       "'optimizer.learning_rate_scaling' must be \"inputs\" or \"none\", got \"linear\""},
      {R"({"storage": {"decoder": "int4"}})", "'storage.decoder' must be \"float32\", \"half\" or \"int8\", got \"int4\""},
      {R"({"storage": {"directions": "f32"}})", "'storage.directions' must be \"f64\" or \"zstd\", got \"f32\""},
      {R"({"storage": {"metadata": "gzip"}})", "'storage.metadata' must be \"raw\" or \"zstd\", got \"gzip\""},
      {R"({"storage": {"cluster_planes": "half"}})",
       "'storage.cluster_planes' must be \"auto\" (as the direction planes) or \"8bit\", got \"half\""},
      {R"({"modulation": {"mean_weight": -1}})", "'modulation.mean_weight' must be a number >= 0"},
      {R"({"modulation": {"channels": 2}})", "'modulation.channels' must be 1 (one coefficient for RGB) or 3"},
      {R"({"training": {"products": "fp8"}})", "'training.products' must be \"float\", \"bf16\" or \"auto\", got \"fp8\""},
      {R"({"training": {"products": "bf16", "backend": "torch"}})", "'training.products' \"bf16\" needs training.backend \"fused\""},
      {R"({"modulation": {"codes": "pca"}})", "'modulation.codes' must be \"linear\" or \"decorrelated\", got \"pca\""},
      {R"({"direction_planes": {"features": 9}})", "'direction_planes.features' must be in 0..8"},
      {R"({"cluster_planes": {"features": 9}})", "'cluster_planes.features' must be in 0..8"},
      {R"({"cluster_planes": {"features": 2, "resolution": 1}})", "'cluster_planes.resolution' must be in 2..64"},
      {R"({"direction_planes": {"features": 2, "resolution": 1}})", "'direction_planes.resolution' must be in 2..64"},
      {R"({"direction_planes": {"size": 2}})", "'direction_planes.size' unknown key"},
      {R"({"optimizer": {"latent_learning_rate": -1}})", "'optimizer.latent_learning_rate' must be >= 0"},
      {R"({"optimizer": {"name": "sgd", "latent_learning_rate": 0.01}})", "needs optimizer.name \"adam\""},
      {R"({"optimizer": {"plane_learning_rate": -0.5}})", "'optimizer.plane_learning_rate' must be >= 0"},
  };
  for (const auto& k : cases) {
    std::string path = test::writeTempText("bad.json", k.json);
    std::string msg = test::errorOf([&] { loadTrainConfig(path); });
    EXPECT_EQ(msg.rfind(path + ": ", 0), 0u) << msg;
    EXPECT_NE(msg.find(k.expect), std::string::npos) << "for " << k.json << "\ngot: " << msg;
    std::filesystem::remove(path);
  }
  EXPECT_NE(test::errorOf([] { loadTrainConfig("/nonexistent/nbtf.json"); }).find("cannot open"), std::string::npos);
}

}  // namespace
}  // namespace nbtf
