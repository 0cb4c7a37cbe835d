// What the optimizer sees (model/training_set.h): the inputs' checks, the hold-out split, the group targets and the step plans.
#include "model/training_set.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <set>
#include <string>
#include <vector>

#include "trainer_fixtures.h"
#include "util/error.h"

namespace nbtf {
namespace {

using testing::material;
using testing::quickConfig;
using testing::TestMaterial;
using test::errorOf;

}  // namespace

TEST(Trainer, BadInputsAreErrors) {
  const TestMaterial& m = material();
  TrainConfig c = quickConfig();
  TrainInputs in = m.clustered();
  in.ids[5] = 4;  // only 4 clusters
  EXPECT_NE(errorOf([&] { trainModel(in, c); }).find("texel 5 has cluster id 4"), std::string::npos);
  in = m.clustered();
  in.ids.pop_back();
  EXPECT_NE(errorOf([&] { trainModel(in, c); }).find("id list has 63 entries"), std::string::npos);
  in = m.perTexel();
  in.encoderInputs = &m.clusterInputs;  // 4 rows for 64 texels
  EXPECT_NE(errorOf([&] { trainModel(in, c); }).find("one encoder input per texel"), std::string::npos);
  in = m.perTexel();
  in.alpha = 0;
  EXPECT_NE(errorOf([&] { trainModel(in, c); }).find("alpha"), std::string::npos);
  MatrixXfCol narrow = m.perTexelInputs.leftCols(30);
  in = m.perTexel();
  in.encoderInputs = &narrow;
  EXPECT_NE(errorOf([&] { trainModel(in, c); }).find("expected 3 x 81"), std::string::npos);
}

TEST(TrainingSet, HoldoutMaskHoldsTheRoundedFractionAndDependsOnTheSeedOnly) {
  auto held = [](const std::vector<std::uint8_t>& mask) { return std::count(mask.begin(), mask.end(), 1); };
  EXPECT_EQ(held(holdoutImageMask(81, 0.2, 5)), 16);  // round(0.2 x 81)
  EXPECT_EQ(held(holdoutImageMask(81, 0, 5)), 0);
  EXPECT_EQ(held(holdoutImageMask(81, 0.001, 5)), 1);  // any fraction > 0 holds one out
  EXPECT_EQ(held(holdoutImageMask(4, 0.99, 5)), 3);    // one image always stays for training
  EXPECT_EQ(holdoutImageMask(81, 0.2, 5), holdoutImageMask(81, 0.2, 5));
  EXPECT_NE(holdoutImageMask(81, 0.2, 5), holdoutImageMask(81, 0.2, 6));
  for (std::uint8_t v : holdoutImageMask(81, 0.5, 3)) EXPECT_TRUE(v == 0 || v == 1);
}

TEST(TrainingSet, SplitsTheImagesAsTheMaskDoes) {
  const TestMaterial& m = material();
  const TrainingSet set(m.clustered(), 0.2, 7, false);
  const std::vector<std::uint8_t> mask = holdoutImageMask(81, 0.2, 7);
  EXPECT_EQ(set.images(), 81);
  EXPECT_EQ(set.groups(), 4);
  EXPECT_EQ(set.texels(), 64);
  EXPECT_EQ(set.holdoutImages().size(), 16u);
  EXPECT_EQ(set.trainImages().size() + set.holdoutImages().size(), 81u);
  for (int i : set.holdoutImages()) EXPECT_TRUE(mask[i] && set.isHoldout(i)) << i;
  for (int i : set.trainImages()) EXPECT_TRUE(!mask[i] && !set.isHoldout(i)) << i;
  EXPECT_TRUE(std::is_sorted(set.trainImages().begin(), set.trainImages().end()));
}

// Clustered: a group's target is its texels' mean (linear / alpha), and withinSse the spread
// around it; per texel: the texel's own value, no spread.
TEST(TrainingSet, TargetsAreTheClusterMeansOrTheTexelsValues) {
  const TestMaterial& m = material();
  const TrainingSet clustered(m.clustered(), 0, 1, false);
  EXPECT_EQ(clustered.outputs(), 3);
  int total = 0;
  for (int g = 0; g < 4; ++g) total += clustered.groupSize(g);
  EXPECT_EQ(total, 64);
  const int images[] = {0, 40, 80};
  for (int g = 0; g < 4; ++g) {
    float out[9];
    clustered.targets(g, images, 3, out);
    EXPECT_EQ(clustered.groupSize(g), static_cast<int>(std::count(m.ids.begin(), m.ids.end(), g)));
    for (int s = 0; s < 3; ++s)
      for (int c = 0; c < 3; ++c) {
        double sum = 0;
        for (int t = 0; t < 64; ++t)
          if (m.ids[t] == g) sum += m.stack.sample(images[s], t, c) / m.alpha;
        EXPECT_NEAR(out[3 * s + c], sum / clustered.groupSize(g), 1e-5) << "group " << g;
      }
  }
  double sse = 0;
  for (int t = 0; t < 64; ++t)
    for (int c = 0; c < 3; ++c) {
      float mean[3];
      clustered.targets(m.ids[t], images + 1, 1, mean);
      const double d = m.stack.sample(40, t, c) / m.alpha - mean[c];
      sse += d * d;
    }
  EXPECT_NEAR(clustered.withinSse(40), sse, 1e-4 * sse);
  EXPECT_GT(sse, 0);

  const TrainingSet perTexel(m.perTexel(), 0, 1, false);
  EXPECT_TRUE(perTexel.perTexel());
  EXPECT_EQ(perTexel.groups(), 64);
  float out[9];
  perTexel.targets(13, images, 3, out);
  for (int s = 0; s < 3; ++s)
    for (int c = 0; c < 3; ++c) EXPECT_FLOAT_EQ(out[3 * s + c], m.stack.sample(images[s], 13, c) / m.alpha);
  EXPECT_EQ(perTexel.withinSse(40), 0);
}

// Groups are drawn in proportion to their texels; a step's plan is a function of (seed, step)
// with distinct training images per tile.
TEST(TrainingSet, StepPlansDrawGroupsBySizeAndDistinctTrainingImages) {
  const TestMaterial& m = material();
  TrainInputs in = m.clustered();
  for (std::int32_t& id : in.ids) id = id == 3 ? 2 : id;  // cluster 3 left empty, 2 twice the size
  const TrainingSet set(in, 0.2, 3, false);
  ASSERT_EQ(set.groupSize(3), 0);
  SplitMix64 rng(11);
  std::vector<int> count(4, 0);
  for (int i = 0; i < 64000; ++i) ++count[set.sampleGroup(rng)];
  EXPECT_EQ(count[3], 0);
  for (int g = 0; g < 3; ++g) EXPECT_NEAR(count[g] / 64000.0, set.groupSize(g) / 64.0, 0.01) << g;

  StepPlan a, b, other;
  planStep(set, 9, 4, 6, 10, a);
  planStep(set, 9, 4, 6, 10, b);
  planStep(set, 9, 5, 6, 10, other);
  EXPECT_EQ(a.tileGroup, b.tileGroup);
  EXPECT_EQ(a.images, b.images);
  EXPECT_NE(a.images, other.images);
  ASSERT_EQ(a.images.size(), 60u);
  for (int t = 0; t < 6; ++t) {
    const std::set<int> distinct(a.images.begin() + 10 * t, a.images.begin() + 10 * t + 10);
    EXPECT_EQ(distinct.size(), 10u);
    for (int i : distinct) EXPECT_FALSE(set.isHoldout(i)) << i;
    EXPECT_EQ(a.distinctGroups[a.tileSlot[t]], a.tileGroup[t]);
  }
}

}  // namespace nbtf
