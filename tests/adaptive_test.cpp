#include "pipeline/adaptive.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "codec/nbtf_file.h"
#include "model_test_material.h"
#include "test_util.h"
#include "util/error.h"

namespace nbtf {
namespace {

// Two clusters, two images (image 1 held out), one RGB output: hand-computed shares.
TEST(Adaptive, ErrorSharesAddTheModelErrorAndTheWithinClusterLeftover) {
  // decoded / best: cluster x image x 3
  std::vector<float> decoded = {1, 1, 1, 9, 9, 9, /**/ 2, 2, 2, 9, 9, 9};
  std::vector<float> best = {1, 1, 2, 5, 5, 5, /**/ 1, 2, 2, 5, 5, 5};
  std::vector<std::int32_t> ids = {0, 0, 1};
  std::vector<int> sizes = {2, 1};
  // Texels 0 and 1 around best (1, 1, 2): (1, 1, 1) and (1, 1, 3) -> energies 3 and 11;
  // texel 2 at its best (1, 2, 2) -> 9.
  std::vector<double> energy = {3, 11, 9};
  std::vector<double> shares = clusterErrorShares(decoded, best, sizes, ids, energy, {0}, 2, 3);
  ASSERT_EQ(shares.size(), 2u);
  EXPECT_DOUBLE_EQ(shares[0], 2 * 1.0 + (14 - 2 * 6.0));  // model 2 x (0 + 0 + 1), leftover 2
  EXPECT_DOUBLE_EQ(shares[1], 1 * 1.0 + 0.0);
  EXPECT_THROW(clusterErrorShares(decoded, best, {2}, ids, energy, {0}, 2, 3), Error);
}

TEST(Adaptive, MergesPairNearDuplicatesCheapestFirst) {
  // Three clusters, latent dim 2; 0 and 1 decode alike, 2 far away.
  std::vector<float> latents = {0, 0, 0.1f, 0, 5, 5};
  std::vector<float> decoded = {1, 1, 1, /**/ 1, 1, 1.01f, /**/ 4, 4, 4};
  std::vector<int> sizes = {3, 5, 4};
  auto merges = chooseMerges(latents, 2, decoded, {}, sizes, {0}, 1, 3, 0.01, 0);
  ASSERT_EQ(merges.size(), 1u);
  EXPECT_EQ(merges[0], std::make_pair(0, 1));  // the smaller joins the larger
  EXPECT_TRUE(chooseMerges(latents, 2, decoded, {}, sizes, {0}, 1, 3, 1e-6, 0).empty());
  // Alike in the model but not in the data: no merge.
  std::vector<float> best = {1, 1, 1, /**/ 2, 2, 2, /**/ 4, 4, 4};
  EXPECT_TRUE(chooseMerges(latents, 2, decoded, best, sizes, {0}, 1, 3, 0.01, 0).empty());
  // Forced (a byte budget): at least one merge even when nothing is a near-duplicate.
  EXPECT_EQ(chooseMerges(latents, 2, decoded, {}, sizes, {0}, 1, 3, 0, 1).size(), 1u);
}

CompressOptions adaptiveOptions() {
  CompressOptions o;
  o.train = testing::quickConfig();
  o.train.epochs = 60;
  o.clusters = 8;
  o.progress = false;
  o.adaptive.enabled = true;
  o.adaptive.stages = 3;
  o.adaptive.initialClusters = 3;
  o.adaptive.maxClusters = 12;
  return o;
}

// The budget's k: bytes that grow by a latent (+2) per cluster and by the same bytes per
// doubling of k (the id stream) are predicted exactly from two stages, so the estimate is the
// largest k that fits; one stage (or two of the same k) gives the linear floor alone; a budget
// below the current file shrinks k; bytes that fell between stages (entropy coding noise) do
// not make later clusters cheaper than the floor.
TEST(Adaptive, BudgetEstimateFollowsTheIdStreamsLogarithmicGrowth) {
  const double latent = 16;
  auto model = [&](int k) { return 40000 + (latent + 2) * k + 1500 * std::log2(k); };
  auto stage = [](int k, double bytes) {
    AdaptiveStage s;
    s.clusters = k, s.bytes = static_cast<std::uint64_t>(std::llround(bytes));
    return s;
  };
  auto largestFitting = [&](double allowed, auto bytesOf) {
    int k = 1;
    while (k < 5000 && bytesOf(k + 1) <= allowed) ++k;
    return k;
  };
  std::vector<AdaptiveStage> stages{stage(100, model(100)), stage(200, model(200))};
  for (double allowed : {model(200) + 900, model(200) + 2000, model(200) + 20000}) {
    const int k = detail::clustersWithinBudget(stages, latent, allowed, 5000);
    EXPECT_NEAR(k, largestFitting(allowed, model), 1) << allowed;
    // A straight line through the two stages (the earlier estimate) gives fewer.
    const double slope = (model(200) - model(100)) / 100;
    EXPECT_GT(k, 200 + static_cast<int>((allowed - model(200)) / slope)) << allowed;
  }
  EXPECT_EQ(detail::clustersWithinBudget(stages, latent, model(200) + 20000, 300), 300);  // capped
  EXPECT_LT(detail::clustersWithinBudget(stages, latent, model(150), 5000), 200);         // shrinks
  EXPECT_EQ(detail::clustersWithinBudget(stages, latent, 10, 5000), 1);

  const std::vector<AdaptiveStage> one{stage(200, 50000)};
  EXPECT_EQ(detail::clustersWithinBudget(one, latent, 50000 + 18 * 50, 5000), 250);
  const std::vector<AdaptiveStage> fell{stage(37, 53264), stage(45, 53096)};
  EXPECT_EQ(detail::clustersWithinBudget(fell, latent, 53096 + 18 * 20, 5000), 65);
  EXPECT_THROW(detail::clustersWithinBudget({}, latent, 1e6, 10), Error);
}

TEST(Adaptive, StagesGrowTheClustersAndAreRecordedInTheFile) {
  testing::TestMaterial m = testing::makeTestMaterial();
  CompressOptions o = adaptiveOptions();
  CompressStats stats;
  CompressedBtf b = compressStack(m.stack, o, stats);
  b.encoderState.clear();  // as compressBtf writes it
  ASSERT_EQ(stats.adaptiveStages.size(), 3u);
  EXPECT_EQ(stats.adaptiveStages[0].clusters, 3);
  EXPECT_GT(stats.adaptiveStages[1].clusters, 3);
  EXPECT_LE(stats.clusters, 12);
  EXPECT_EQ(stats.adaptiveStages.back().clusters, stats.clusters);
  EXPECT_EQ(b.latentRows, stats.clusters);
  EXPECT_EQ(stats.adaptiveStages.back().steps, stats.steps);
  EXPECT_EQ(stats.adaptiveStages.back().rmseTrain, stats.rmseTrain);
  EXPECT_LT(stats.adaptiveStages.back().rmseTrain, stats.adaptiveStages[0].rmseTrain);
  // The recorded bytes of the last stage are the file's.
  EXPECT_EQ(stats.adaptiveStages.back().bytes, serializeNbtf(b).size());
  nlohmann::json meta = nlohmann::json::parse(b.metadataJson);
  ASSERT_TRUE(meta.contains("adaptive"));
  EXPECT_EQ(meta["adaptive"]["stages"].size(), 3u);
  EXPECT_EQ(meta["clustering"]["k"].get<int>(), stats.clusters);
  const std::string generation = meta["adaptive"]["generation"].get<std::string>();
  EXPECT_EQ(generation.size(), static_cast<std::size_t>(stats.clusters));
  EXPECT_NE(generation.find('1'), std::string::npos);  // some clusters came from splits
  nlohmann::json j = nlohmann::json::parse(compressStatsJson(stats));
  EXPECT_EQ(j["adaptive"]["stages"].size(), 3u);
  EXPECT_NE(formatCompressSummary(stats).find("adaptive: 3 stages, k 3 -> "), std::string::npos)
      << formatCompressSummary(stats);
}

TEST(Adaptive, SameSeedSameBytes) {
  testing::TestMaterial m = testing::makeTestMaterial();
  CompressOptions o = adaptiveOptions();
  CompressStats s1, s2;
  EXPECT_EQ(serializeNbtf(compressStack(m.stack, o, s1)), serializeNbtf(compressStack(m.stack, o, s2)));
}

TEST(Adaptive, SizeBudgetIsNeverExceeded) {
  testing::TestMaterial m = testing::makeTestMaterial();
  CompressOptions o = adaptiveOptions();
  o.adaptive.maxClusters = 0;
  CompressStats grown;
  compressStack(m.stack, o, grown);  // doubling: 3 -> 12
  const std::uint64_t unboundedBytes = grown.adaptiveStages.back().bytes;
  ASSERT_GT(grown.clusters, 3);
  // Budgets below the unbounded file's size, down to about the first stage's (whose entry in
  // the metadata had one stage, not three).
  for (std::uint64_t budget : {unboundedBytes - 40, unboundedBytes - 100, grown.adaptiveStages[0].bytes + 300}) {
    o.adaptive.sizeBudget = budget;
    CompressStats stats;
    CompressedBtf b = compressStack(m.stack, o, stats);
    b.encoderState.clear();  // as compressBtf writes it
    EXPECT_LE(serializeNbtf(b).size(), budget) << "budget " << budget;
    EXPECT_EQ(stats.adaptiveStages.back().bytes, serializeNbtf(b).size());
  }
  o.adaptive.sizeBudget = 1000;  // less than the decoder alone
  CompressStats stats;
  EXPECT_THROW(compressStack(m.stack, o, stats), Error);
}

// --time-budget alone: the stages end at fractions of the budget on the training clock, which
// the checkpoint carries from stage to stage, so every stage runs and the last one ends the run.
TEST(Adaptive, ATimeBudgetAloneIsSharedAcrossTheStages) {
  testing::TestMaterial m = testing::makeTestMaterial();
  CompressOptions o = adaptiveOptions();
  o.train.epochs = 0;
  o.train.minSteps = o.train.maxSteps = 0;
  o.train.timeBudgetSeconds = 3;
  CompressStats stats;
  CompressedBtf b = compressStack(m.stack, o, stats);
  ASSERT_EQ(stats.adaptiveStages.size(), 3u);
  EXPECT_EQ(stats.adaptiveStages[0].clusters, 3);
  for (std::size_t i = 1; i < stats.adaptiveStages.size(); ++i)
    EXPECT_GE(stats.adaptiveStages[i].steps, stats.adaptiveStages[i - 1].steps) << i;
  EXPECT_GT(stats.steps, 0);
  EXPECT_EQ(stats.adaptiveStages.back().steps, stats.steps);
  EXPECT_EQ(b.latentRows, stats.clusters);
  EXPECT_GT(stats.rmseTrain, 0);
  b.encoderState.clear();  // as compressBtf writes it
  EXPECT_EQ(stats.adaptiveStages.back().bytes, serializeNbtf(b).size());
}

TEST(Adaptive, OptionsAreChecked) {
  testing::TestMaterial m = testing::makeTestMaterial();
  CompressOptions o = adaptiveOptions();
  CompressStats stats;
  o.adaptive.stages = 0;
  EXPECT_THROW(compressStack(m.stack, o, stats), Error);
  o = adaptiveOptions();
  o.clusters = 0;
  EXPECT_THROW(compressStack(m.stack, o, stats), Error);
}

// Ctrl-C anywhere in an adaptive run, then --resume: the same bytes as one uninterrupted run
// (mid first stage, exactly at a stage's end, mid a later stage, twice in one run).
TEST(Adaptive, InterruptedRunResumesToTheSameBytes) {
  testing::TestMaterial m = testing::makeTestMaterial();
  test::TempDir dir;
  CompressOptions o = adaptiveOptions();
  o.checkpointPath = dir / "run.ckpt";
  CompressStats whole;
  const std::vector<std::uint8_t> expected = serializeNbtf(compressStack(m.stack, o, whole));
  ASSERT_EQ(whole.adaptiveStages.size(), 3u);
  const std::int64_t end1 = whole.adaptiveStages[0].steps, end2 = whole.adaptiveStages[1].steps;
  ASSERT_GT(end1, 2);
  ASSERT_GT(end2, end1 + 2);
  for (const std::vector<std::int64_t>& stops :
       {std::vector<std::int64_t>{end1 / 2}, {end1}, {(end1 + end2) / 2}, {end1 / 2, end2 + 1}}) {
    std::filesystem::remove(o.checkpointPath);
    std::filesystem::remove(adaptiveStatePath(o.checkpointPath));
    CompressOptions run = o;
    std::atomic<bool> stop{false};
    std::int64_t stopAt = 0;
    run.stopFlag = &stop;
    run.train.monitor = [&](const TrainStatus& s) {
      if (s.step >= stopAt) stop = true;
    };
    for (std::int64_t at : stops) {
      stopAt = at;
      stop = false;
      CompressStats stats;
      compressStack(m.stack, run, stats);
      ASSERT_TRUE(stats.interrupted) << "stop at " << at;
      EXPECT_TRUE(std::filesystem::exists(adaptiveStatePath(o.checkpointPath)));
      run.train.resume = true;
    }
    run.train.monitor = nullptr;
    stop = false;
    CompressStats stats;
    EXPECT_EQ(serializeNbtf(compressStack(m.stack, run, stats)), expected) << "stopped at " << stops.front();
    EXPECT_EQ(stats.clusters, whole.clusters);
  }
}

TEST(Adaptive, ResumeRefusesAnotherRunsState) {
  testing::TestMaterial m = testing::makeTestMaterial();
  test::TempDir dir;
  CompressOptions o = adaptiveOptions();
  o.checkpointPath = dir / "run.ckpt";
  std::atomic<bool> stop{false};
  o.stopFlag = &stop;
  o.train.monitor = [&](const TrainStatus& s) {
    if (s.step >= 3) stop = true;
  };
  CompressStats stats;
  compressStack(m.stack, o, stats);
  ASSERT_TRUE(stats.interrupted);
  stop = false;
  o.train.monitor = nullptr;
  o.train.resume = true;
  o.adaptive.maxClusters = 10;  // other options: the saved clusters are not this run's
  test::expectErrorContaining([&] { compressStack(m.stack, o, stats); },
                              {adaptiveStatePath(o.checkpointPath), "other options"});
  // A damaged state names its file.
  o.adaptive.maxClusters = 12;
  std::ofstream(adaptiveStatePath(o.checkpointPath)) << "{\"format\": \"nbtf adaptive state 1\"";
  test::expectErrorContaining([&] { compressStack(m.stack, o, stats); },
                              {adaptiveStatePath(o.checkpointPath), "damaged"});
}

}  // namespace
}  // namespace nbtf
