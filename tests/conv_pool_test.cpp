// The encoder's fused Conv1d + MaxPool1d (model/autograd/conv_pool.h) against torch's modules.
#include <gtest/gtest.h>

#include "support/torch_reference.h"

namespace nbtf {

TEST(Trainer, FusedConvPoolMatchesTorch) {
  EXPECT_EQ(convPoolReferenceError(1, 3, 3, 4, 30), 0.0);
  EXPECT_EQ(convPoolReferenceError(2, 2, 5, 3, 31), 0.0);    // a tail that pooling drops
  EXPECT_EQ(convPoolReferenceError(3, 1, 1, 1, 3), 0.0);     // a single window
  EXPECT_EQ(convPoolReferenceError(4, 5, 8, 16, 245), 0.0);  // past the 16-wide vector loops
  // Channel blocks of 8 and 4 with zero-padded rows (12 = 8 + 4, 9 and 3 padded to 12 and 4),
  // one input channel, windows that fill whole vectors exactly (48) or one short (47, 46).
  EXPECT_EQ(convPoolReferenceError(5, 2, 1, 12, 47), 0.0);
  EXPECT_EQ(convPoolReferenceError(6, 2, 3, 9, 48), 0.0);
  EXPECT_EQ(convPoolReferenceError(7, 3, 4, 5, 46), 0.0);
  EXPECT_EQ(convPoolReferenceError(8, 1, 2, 20, 97), 0.0);
  EXPECT_EQ(convPoolReferenceError(9, 2, 16, 4, 5), 0.0);
  EXPECT_EQ(convPoolReferenceError(10, 2, 3, 4, 800), 0.0);  // chunks of 128 windows, the last partial
}

}  // namespace nbtf
