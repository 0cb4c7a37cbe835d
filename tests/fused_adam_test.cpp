// The fused Adam step (model/autograd/fused_adam.h) against torch::optim::Adam.
#include <gtest/gtest.h>

#include "support/torch_reference.h"

namespace nbtf {

TEST(Trainer, FusedAdamMatchesTorch) {
  // The decoder's and encoder's parameter sizes, a tail past the 16-wide loop, one element.
  EXPECT_LT(fusedAdamReferenceError(1, {106 * 106, 106, 31104, 8}, 25, 0.002), 1e-5);
  EXPECT_LT(fusedAdamReferenceError(2, {17, 1}, 40, 0.08), 1e-5);
}

}  // namespace nbtf
