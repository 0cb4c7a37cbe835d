// The decoder's hand-written training pass (model/autograd/decoder_backprop.h) against autograd, float and bf16.
#include <gtest/gtest.h>

#include <vector>

#include "model/kernels/dense_kernels.h"
#include "model/trainer.h"
#include "support/torch_reference.h"

namespace nbtf {

TEST(Trainer, HandWrittenBackpropMatchesAutograd) {
  ModelConfig model;
  EXPECT_LT(decoderBackpropError(model, 3, 4, 7), 1e-5);
  ModelConfig small;
  small.latentDim = 5, small.decoderWidth = 17, small.decoderLayers = 2;
  EXPECT_LT(decoderBackpropError(small, 4, 1, 9), 1e-5);
  small.decoderLayers = 6;
  EXPECT_LT(decoderBackpropError(small, 5, 3, 2), 1e-5);
  // Several 512-row chunks with a short last one, split between two threads; a width
  // whose padded rows (with the bias column) need two vector panels.
  ModelConfig wide;
  wide.decoderWidth = 130;
  for (int threads : {1, 2}) {
    EXPECT_LT(decoderBackpropError(model, 6, 5, 211, threads), 1e-5) << threads << " threads";
    EXPECT_LT(decoderBackpropError(wide, 7, 2, 300, threads), 1e-5) << threads << " threads";
  }
  // The half-vector direction inputs (8 per row instead of 4), over several chunks too.
  ModelConfig half;
  half.directionInputs = DirectionEncoding::StereographicHalf;
  EXPECT_LT(decoderBackpropError(half, 8, 4, 7), 1e-5);
  for (int threads : {1, 2}) EXPECT_LT(decoderBackpropError(half, 9, 5, 211, threads), 1e-5) << threads << " threads";
  // The direction planes' features get each row's gradient of its last direction inputs.
  for (int threads : {1, 2}) {
    EXPECT_LT(decoderInputGradientError(model, 6, 5, 211, threads), 1e-5) << threads << " threads";
    EXPECT_LT(decoderInputGradientError(wide, 7, 2, 300, threads), 1e-5) << threads << " threads";
  }
}

TEST(Trainer, HandWrittenBackpropIsTheSameOnAnyThreadCount) {
  // Threads take 512-row chunks as they free up and the chunks' sums are added in chunk
  // order: the result must not depend on the thread count or on which thread ran which chunk.
  ModelConfig model;
  const std::vector<float> one = decoderTrainStepResult(model, 11, 9, 300, 1);
  EXPECT_GT(one.size(), 24000u);
  for (int run = 0; run < 3; ++run) EXPECT_EQ(decoderTrainStepResult(model, 11, 9, 300, 2), one) << "run " << run;
  EXPECT_NE(decoderTrainStepResult(model, 12, 9, 300, 1), one);  // a different batch does differ
}

TEST(Trainer, Bf16ProductsStayCloseToAutograd) {
  // The hidden layers' operands rounded to 8 significant bits, float sums: the gradients move
  // by well under 0.5% of their largest magnitude (measured 0.04-0.13% over eight batches of
  // each shape), and they do move.
  ModelConfig model, wide;
  wide.decoderWidth = 130;  // odd padded sums (131 inputs with the bias column), two panels
  for (int threads : {1, 2}) {
    const double err = decoderBackpropError(model, 6, 5, 211, threads, true);
    EXPECT_LT(err, 5e-3) << threads << " threads";
    EXPECT_GT(err, 1e-5) << "the products did not change: bf16 not applied";
    EXPECT_LT(decoderBackpropError(wide, 7, 2, 301, threads, true), 5e-3) << threads << " threads";
  }
  // Odd width, many layers, and 6 rows: sums of few terms, whose roundings do not average out
  // (measured 0.04-1.6% over eight batches).
  ModelConfig small;
  small.latentDim = 5, small.decoderWidth = 17, small.decoderLayers = 6;
  EXPECT_LT(decoderBackpropError(small, 5, 3, 2, 1, true), 3e-2);
  // One row's gradient of its direction inputs is a single sum over the units, not a sum over
  // rows: the hidden layers' roundings do not average out in it (measured 9-15% of the
  // largest); the planes add it up over many rows. A wrong layout or a missing term would be
  // of the order of the largest itself.
  for (int threads : {1, 2}) {
    EXPECT_LT(decoderInputGradientError(model, 6, 5, 211, threads, true), 0.3) << threads << " threads";
    EXPECT_LT(decoderInputGradientError(wide, 7, 2, 301, threads, true), 0.3) << threads << " threads";
  }
}

TEST(Trainer, Bf16ProductsAreTheSameOnAnyThreadCountAndBuild) {
  ModelConfig model;
  const std::vector<float> one = decoderTrainStepResult(model, 11, 9, 300, 1, true);
  EXPECT_EQ(decoderTrainStepResult(model, 11, 9, 300, 2, true), one);
  EXPECT_NE(decoderTrainStepResult(model, 11, 9, 300, 1, false), one);
  // The portable build (every CPU) gives the instruction's bits.
  detail::setBf16ProductsPortable(true);
  const std::vector<float> portable = decoderTrainStepResult(model, 11, 9, 300, 2, true);
  detail::setBf16ProductsPortable(false);
  EXPECT_EQ(portable, one);
}

}  // namespace nbtf
