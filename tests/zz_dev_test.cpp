#include <gtest/gtest.h>
#include <cstdlib>
#include "model_test_material.h"
namespace nbtf {
TEST(Dev, Sweep) {
  if (!std::getenv("NBTF_DEV")) GTEST_SKIP();
  auto m = testing::makeTestMaterial();
  printf("floor %f baseline %f\n", testing::clusterFloorRmse(m), testing::imageMeanRmse(m));
  for (int epochs : {150, 600}) for (double polish : {0.0, 0.1}) for (double lr : {3e-3, 1e-2}) {
    TrainConfig c = testing::quickConfig();
    c.epochs = epochs; c.polishFraction = polish; c.learningRate = lr;
    auto r = trainModel(m.clustered(), c);
    auto r2 = trainModel(m.perTexel(), c);
    printf("epochs %d polish %.1f lr %g: clustered rmse %.4f loss %.3e steps %ld | per-texel %.4f steps %ld  %.1fs\n", epochs, polish, lr, r.rmseTrain, r.finalLoss, (long)r.steps, r2.rmseTrain, (long)r2.steps, r.seconds+r2.seconds);
  }
}
}
