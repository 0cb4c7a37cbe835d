// Training checkpoints (model/train_checkpoint.cpp): written on a stop, refused when corrupt or of another setup, resumed exactly.
#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <string>
#include <vector>

#include "model/trainer.h"
#include "trainer_fixtures.h"
#include "util/error.h"

namespace nbtf {
namespace {

using testing::material;
using testing::quickConfig;
using testing::sameModel;
using testing::tempPath;
using testing::TestMaterial;
using test::errorOf;

// Per-cluster means of the standardized rows: the test material's representatives.
MatrixXfCol meanRows(const MatrixXfCol& x, const std::vector<std::int32_t>& ids, int k) {
  MatrixXfCol out = MatrixXfCol::Zero(k, x.cols());
  std::vector<int> count(k, 0);
  for (std::size_t t = 0; t < ids.size(); ++t) out.row(ids[t]) += x.row(t), ++count[ids[t]];
  for (int c = 0; c < k; ++c) out.row(c) /= static_cast<float>(count[c]);
  return out;
}

TEST(Trainer, ResumeAfterInterruptionEqualsUninterruptedRun) {
  const TestMaterial& m = material();
  TrainConfig c = quickConfig();
  c.epochs = 80;  // 80 steps, the last 8 with the encoder frozen
  TrainResult full = trainModel(m.clustered(), c);
  ASSERT_GT(full.steps, 40);

  std::string ckpt = tempPath("resume.ckpt");
  std::filesystem::remove(ckpt);
  c.checkpointPath = ckpt;
  c.stopAtStep = 37;
  TrainResult part = trainModel(m.clustered(), c);
  EXPECT_TRUE(part.interrupted);
  EXPECT_EQ(part.steps, 37);
  EXPECT_EQ(part.rmseTrain, -1);
  ASSERT_TRUE(std::filesystem::exists(ckpt));

  c.resume = true;
  c.stopAtStep = 76;  // inside the polish phase (encoder frozen from step 72)
  TrainResult part2 = trainModel(m.clustered(), c);
  EXPECT_EQ(part2.resumedFromStep, 37);
  EXPECT_TRUE(part2.interrupted);

  c.stopAtStep = 0;
  TrainResult resumed = trainModel(m.clustered(), c);
  EXPECT_EQ(resumed.resumedFromStep, 76);
  EXPECT_EQ(resumed.steps, full.steps);
  EXPECT_FALSE(resumed.interrupted);
  EXPECT_TRUE(sameModel(resumed, full));
  EXPECT_EQ(resumed.rmseTrain, full.rmseTrain);
  std::filesystem::remove(ckpt);
}

// A time budget means the same over resumes as in one run: the resumed run spends what the
// interrupted one left (it used to stop at once and return the under-trained model).
TEST(Trainer, ResumedTimeBudgetSpendsTheRemainingBudget) {
  const TestMaterial& m = material();
  TrainConfig c = quickConfig();
  c.epochs = 0;
  c.timeBudgetSeconds = 3;
  c.checkpointPath = tempPath("budget.ckpt");
  std::filesystem::remove(c.checkpointPath);
  c.stopAtStep = 5;
  TrainResult part = trainModel(m.clustered(), c);
  ASSERT_TRUE(part.interrupted);
  ASSERT_EQ(part.steps, 5);
  const CheckpointSummary first = readCheckpointSummary(c.checkpointPath);
  EXPECT_EQ(first.step, 5);
  EXPECT_GT(first.elapsedSeconds, 0);
  if (first.elapsedSeconds >= 1.5)
    GTEST_SKIP() << "5 steps took " << first.elapsedSeconds << " s here: too slow for the test's budget";

  c.resume = true;
  c.stopAtStep = 0;
  TrainResult resumed = trainModel(m.clustered(), c);
  EXPECT_FALSE(resumed.interrupted);
  EXPECT_EQ(resumed.resumedFromStep, 5);
  EXPECT_GT(resumed.steps, 5 + 20) << "the resumed run did no training";
  // The budget's clock carries over: the finished run's recorded training time is the
  // interrupted run's plus its own, so the budget counts both, not each alone.
  const CheckpointSummary last = readCheckpointSummary(c.checkpointPath);
  EXPECT_EQ(last.step, resumed.steps);
  EXPECT_GE(last.elapsedSeconds, first.elapsedSeconds + resumed.trainSeconds);
  std::filesystem::remove(c.checkpointPath);
}

TEST(Trainer, StopFlagWritesACheckpoint) {
  const TestMaterial& m = material();
  TrainConfig c = quickConfig();
  std::atomic<bool> stop{true};
  c.stopFlag = &stop;
  c.checkpointPath = tempPath("stop.ckpt");
  std::filesystem::remove(c.checkpointPath);
  TrainResult r = trainModel(m.perTexel(), c);
  EXPECT_TRUE(r.interrupted);
  EXPECT_EQ(r.steps, 0);
  EXPECT_TRUE(std::filesystem::exists(c.checkpointPath));
  // A checkpoint from another setup is refused with the path in the message.
  c.stopFlag = nullptr;
  c.resume = true;
  std::string msg = errorOf([&] { trainModel(m.clustered(), c); });
  EXPECT_NE(msg.find(c.checkpointPath), std::string::npos) << msg;
  EXPECT_NE(msg.find("different setup"), std::string::npos) << msg;
  std::filesystem::remove(c.checkpointPath);
}

TEST(Trainer, CorruptCheckpointIsAClearError) {
  const TestMaterial& m = material();
  TrainConfig c = quickConfig();
  c.checkpointPath = test::writeTempText("trainer_test_corrupt.ckpt", "this is not a checkpoint");
  c.resume = true;
  std::string msg = errorOf([&] { trainModel(m.perTexel(), c); });
  EXPECT_NE(msg.find(c.checkpointPath), std::string::npos) << msg;
  EXPECT_NE(msg.find("is not an nbtf checkpoint"), std::string::npos) << msg;
  std::filesystem::remove(c.checkpointPath);
}

// Adaptive clustering's warm start (pipeline/adaptive.h): the clusters change between stages,
// the parameters do not. Latents are the encoder's outputs, not parameters, so the optimizer's
// state after a split is the previous stage's, bit for bit, and only the latents of the
// changed clusters change (they come from the encoder on their new representatives).
TEST(Trainer, WarmStartAcrossASplitKeepsWeightsAndAdamStateBitForBit) {
  const TestMaterial& m = material();
  TrainConfig c = quickConfig();
  c.epochs = 40;
  const std::string ckpt = tempPath("warm_split.ckpt");
  std::filesystem::remove(ckpt);
  c.checkpointPath = ckpt;
  c.stopAtStep = 15;
  TrainResult before = trainModel(m.clustered(), c);
  ASSERT_TRUE(before.interrupted);
  const CheckpointState atSplit = readCheckpointState(ckpt);
  EXPECT_EQ(atSplit.step, 15);

  // Split cluster 0: its texels in even columns become cluster 4.
  std::vector<std::int32_t> ids = m.ids;
  for (std::size_t t = 0; t < ids.size(); ++t)
    if (ids[t] == 0 && (t % 8) % 2 == 0) ids[t] = 4;
  MatrixXfCol reps = meanRows(m.perTexelInputs, ids, 5);
  TrainInputs split = m.clustered();
  split.encoderInputs = &reps;
  split.ids = ids;
  // A resume refuses another set of clusters; a warm start takes it.
  c.resume = true;
  EXPECT_THROW(trainModel(split, c), Error);
  c.resume = false;
  c.warmStart = true;
  TrainResult after = trainModel(split, c);  // stopAtStep 15: no steps, the state right after the split
  EXPECT_EQ(after.resumedFromStep, 15);
  EXPECT_EQ(after.steps, 15);
  const CheckpointState state = readCheckpointState(ckpt);
  EXPECT_NE(state.fingerprint, atSplit.fingerprint);  // another set of clusters...
  ASSERT_EQ(state.tensors.size(), atSplit.tensors.size());  // ...the same parameters and state
  int moments = 0, steps = 0, encoderTensors = 0, decoderTensors = 0;
  for (std::size_t i = 0; i < state.tensors.size(); ++i) {
    const std::string& name = state.tensors[i].first;
    EXPECT_EQ(name, atSplit.tensors[i].first);
    EXPECT_TRUE(state.tensors[i].second == atSplit.tensors[i].second) << name << " changed across the split";
    moments += name.find("exp_avg") != std::string::npos;
    steps += name.rfind("optimizer/", 0) == 0 && name.find("/step") != std::string::npos;
    encoderTensors += name.rfind("encoder/", 0) == 0;
    decoderTensors += name.rfind("decoder/", 0) == 0;
  }
  EXPECT_GT(moments, 0) << "no Adam moments in the checkpoint";
  EXPECT_GT(steps, 0) << "no Adam step counts in the checkpoint";
  EXPECT_GT(encoderTensors, 0);
  EXPECT_GT(decoderTensors, 0);
  // The decoder is the same; unchanged clusters keep their latents, the split ones get new ones.
  EXPECT_TRUE(after.decoder.layers[0].weight == before.decoder.layers[0].weight);
  ASSERT_EQ(after.latentRows, 5);
  const int d = c.model.latentDim;
  for (int g = 1; g < 4; ++g)
    for (int j = 0; j < d; ++j) EXPECT_EQ(after.latents[g * d + j], before.latents[g * d + j]) << "cluster " << g;
  EXPECT_NE(std::vector<float>(after.latents.begin(), after.latents.begin() + d),
            std::vector<float>(before.latents.begin(), before.latents.begin() + d));

  // Training goes on from step 15 to the end of the one schedule.
  c.stopAtStep = 0;
  TrainResult done = trainModel(split, c);
  EXPECT_EQ(done.steps, 40);
  EXPECT_FALSE(done.interrupted);
  EXPECT_GT(done.rmseTrain, 0);
  std::filesystem::remove(ckpt);

  c.checkpointPath = tempPath("no_such_warm.ckpt");
  std::filesystem::remove(c.checkpointPath);
  EXPECT_THROW(trainModel(split, c), Error);  // a warm start needs its checkpoint
}

// A stage continued without any change of the clusters is the uninterrupted run: the same
// steps (planStep numbers them globally), the same bits.
TEST(Trainer, WarmStartWithUnchangedClustersEqualsTheUninterruptedRun) {
  const TestMaterial& m = material();
  TrainConfig c = quickConfig();
  c.epochs = 40;
  TrainResult full = trainModel(m.clustered(), c);
  const std::string ckpt = tempPath("warm_same.ckpt");
  std::filesystem::remove(ckpt);
  c.checkpointPath = ckpt;
  c.stopAtStep = 15;
  trainModel(m.clustered(), c);
  c.stopAtStep = 0;
  c.warmStart = true;
  TrainResult continued = trainModel(m.clustered(), c);
  EXPECT_EQ(continued.resumedFromStep, 15);
  EXPECT_TRUE(sameModel(continued, full));
  EXPECT_EQ(continued.rmseTrain, full.rmseTrain);
  std::filesystem::remove(ckpt);
}

}  // namespace
}  // namespace nbtf
