// The encoder's BatchNorm in training (model/autograd/batch_norm.h) against torch::nn::BatchNorm1d.
#include <gtest/gtest.h>

#include "support/torch_reference.h"

namespace nbtf {

TEST(Trainer, BatchNormMatchesTorchInTraining) {
  // Values, all gradients and the running statistics; float rounding differs from torch's.
  for (int threads : {1, 2}) {  // torch's own sums change order with its thread count
    EXPECT_LT(batchNormReferenceError(1, 64, 4, 2187, false, threads), 1e-5);  // the first encoder block
    EXPECT_LT(batchNormReferenceError(2, 3, 16, 5, false, threads), 1e-5);
    EXPECT_LT(batchNormReferenceError(3, 2, 3, 1, false, threads), 1e-5);      // two values per channel
  }
  // A constant channel: finite, no NaN. torch's float mean of the constant is off by an ulp,
  // which 1 / sqrt(eps) = 316 amplifies; ours (summed in double) is exact.
  EXPECT_LT(batchNormReferenceError(4, 8, 3, 40, true, 2), 1e-4);
}

}  // namespace nbtf
