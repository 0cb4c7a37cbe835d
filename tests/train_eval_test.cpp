// The trained model's exact per-texel RMSE (model/train_eval.cpp): from per-cluster sums, equal to the texel-by-texel value, and skippable.
#include <gtest/gtest.h>

#include <vector>

#include "model/trainer.h"
#include "trainer_fixtures.h"

namespace nbtf {
namespace {

using testing::allImages;
using testing::asInts;
using testing::material;
using testing::quickConfig;
using testing::TestMaterial;

}  // namespace

TEST(Trainer, ClusteredModeLearnsAndReportsExactPerTexelRmse) {
  const TestMaterial& m = material();
  TrainConfig c = quickConfig();
  c.epochs = 600;  // an epoch is only 4 clusters x 81 images here
  TrainResult r = trainModel(m.clustered(), c);
  EXPECT_EQ(r.latentRows, m.clusters);
  // One latent per cluster cannot represent the spread inside a cluster: the floor is the
  // RMSE of the exact cluster means; training must get close to it and far below the baseline.
  double floor = testing::clusterFloorRmse(m), baseline = testing::imageMeanRmse(m);
  EXPECT_LT(floor, 0.6 * baseline);
  EXPECT_GE(r.rmseTrain, floor * 0.999);
  EXPECT_LT(r.rmseTrain, floor + 0.1 * (baseline - floor)) << "floor " << floor << " baseline " << baseline;
  // Computed by the trainer from per-cluster sums; recomputed here texel by texel.
  EXPECT_NEAR(testing::decodedRmse(m, r, asInts(m.ids), allImages(m)), r.rmseTrain, 1e-4 + 1e-3 * r.rmseTrain);
}

// Without the final evaluation (the compressor measures the stored file instead) the same
// training gives the same model, no RMSE (-1), and still the floor from training's own sums.
TEST(Trainer, FinalEvaluationCanBeLeftOut) {
  const TestMaterial& m = material();
  TrainConfig c = quickConfig();
  c.epochs = 20;
  c.holdoutFraction = 0.1;
  const TrainResult measured = trainModel(m.clustered(), c);
  c.finalEvaluation = false;
  const TrainResult unmeasured = trainModel(m.clustered(), c);
  EXPECT_GT(measured.rmseTrain, 0);
  EXPECT_GT(measured.rmseHoldout, 0);
  EXPECT_EQ(unmeasured.rmseTrain, -1);
  EXPECT_EQ(unmeasured.rmseHoldout, -1);
  EXPECT_EQ(unmeasured.rmseFloor, measured.rmseFloor);
  EXPECT_GT(unmeasured.rmseFloor, 0);
  EXPECT_EQ(unmeasured.steps, measured.steps);
  EXPECT_EQ(unmeasured.latents, measured.latents);
}

}  // namespace nbtf
