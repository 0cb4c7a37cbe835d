// The encoder's last linear layer (model/autograd/small_linear.h) against torch::nn::Linear.
#include <gtest/gtest.h>

#include "support/torch_reference.h"

namespace nbtf {

TEST(Trainer, SmallLinearMatchesTorch) {
  EXPECT_EQ(smallLinearReferenceError(1, 64, 3888, 8), 0.0);  // the encoder's shape for N = 6561
  EXPECT_EQ(smallLinearReferenceError(2, 1, 5, 3), 0.0);      // a single input
  EXPECT_EQ(smallLinearReferenceError(3, 7, 2, 11), 0.0);
}

}  // namespace nbtf
