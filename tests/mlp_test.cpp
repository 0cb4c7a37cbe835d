#include "codec/mlp.h"
#include "support/mlp_reference.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "support/torch_reference.h"
#include "model/trainer.h"
#include "util/error.h"

namespace nbtf {
namespace {

DenseLayer layer(int in, int out, std::vector<float> w, std::vector<float> b, Activation a) {
  DenseLayer l;
  l.in = in, l.out = out, l.weight = std::move(w), l.bias = std::move(b), l.activation = a;
  return l;
}

}  // namespace

TEST(Mlp, ForwardEqualsHandComputation) {
  Mlp mlp;
  // 2 -> 3 (ReLU) -> 2 (linear); weights out x in, row-major.
  mlp.layers.push_back(layer(2, 3, {1, 2, -1, 0, 0.5f, -3}, {0.5f, 0, 1}, Activation::Relu));
  mlp.layers.push_back(layer(3, 2, {1, -1, 2, 0, 3, 1}, {0, -0.25f}, Activation::None));
  RowMatrix in(2, 2);
  in << 1, 2, -1, 0.5f;
  RowMatrix out = mlpForward(mlp, in);
  // Row 0: h = relu([1*1 + 2*2 + 0.5, -1*1 + 0*2 + 0, 0.5*1 - 3*2 + 1]) = [5.5, 0, 0]
  //        y = [5.5 - 0 + 0, 0 + 0 + 0 - 0.25] = [5.5, -0.25]
  // Row 1: h = relu([-1 + 1 + 0.5, 1 + 0, -0.5 - 1.5 + 1]) = [0.5, 1, 0]
  //        y = [0.5 - 1 + 0, 3 * 1 - 0.25] = [-0.5, 2.75]
  ASSERT_EQ(out.rows(), 2);
  ASSERT_EQ(out.cols(), 2);
  EXPECT_FLOAT_EQ(out(0, 0), 5.5f);
  EXPECT_FLOAT_EQ(out(0, 1), -0.25f);
  EXPECT_FLOAT_EQ(out(1, 0), -0.5f);
  EXPECT_FLOAT_EQ(out(1, 1), 2.75f);
}

TEST(Mlp, SigmoidActivation) {
  Mlp mlp;
  mlp.layers.push_back(layer(1, 1, {2}, {-1}, Activation::Sigmoid));
  RowMatrix in(1, 1);
  in << 1.5f;
  EXPECT_NEAR(mlpForward(mlp, in)(0, 0), 1 / (1 + std::exp(-2.0)), 1e-6);
}

TEST(Mlp, LargeBatchesMatchRowByRow) {
  // The forward pass is split into row blocks over threads; every row must come out as if
  // it were evaluated alone.
  Mlp mlp = decoderShape(ModelConfig{});
  std::uint32_t s = 7;
  auto rnd = [&] { return ((s = s * 1664525u + 1013904223u) >> 8) / float(1 << 24) - 0.5f; };
  for (auto& l : mlp.layers) {
    for (auto& w : l.weight) w = rnd() * 0.3f;
    for (auto& b : l.bias) b = rnd() * 0.1f;
  }
  RowMatrix in(2000, mlp.inputSize());
  for (Eigen::Index i = 0; i < in.size(); ++i) in.data()[i] = rnd() * 2;
  RowMatrix all = mlpForward(mlp, in);
  for (int r : {0, 511, 512, 1023, 1999}) {
    RowMatrix one = mlpForward(mlp, in.row(r));
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(all(r, c), one(0, c), 1e-5f) << "row " << r;
  }
}

TEST(Mlp, ValidateRejectsBrokenNetworks) {
  Mlp ok;
  ok.layers.push_back(layer(2, 1, {1, 1}, {0}, Activation::None));
  EXPECT_NO_THROW(ok.validate());
  Mlp empty;
  EXPECT_THROW(empty.validate(), Error);
  Mlp shape = ok;
  shape.layers[0].weight.pop_back();
  EXPECT_THROW(shape.validate(), Error);
  Mlp chain = ok;
  chain.layers.push_back(layer(2, 1, {1, 1}, {0}, Activation::None));  // takes 2, gets 1
  EXPECT_THROW(chain.validate(), Error);
  Mlp nan = ok;
  nan.layers[0].bias[0] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(nan.validate(), Error);
  RowMatrix wrongWidth(1, 3);
  EXPECT_THROW(mlpForward(ok, wrongWidth), Error);
}

TEST(Mlp, PaperDecoderHas24383Parameters) {
  ModelConfig paper;
  paper.directionInputs = DirectionEncoding::Stereographic;
  paper.planeFeatures = 0;
  // The default's Fourier inputs (2 octaves) add 16 first-layer inputs and its direction
  // planes (3 x 4 features) 12 more: 28 x 106 weights.
  EXPECT_EQ(decoderShape(ModelConfig{}).parameterCount(), 24383u + 28 * 106);
  Mlp decoder = decoderShape(paper);
  ASSERT_EQ(decoder.layers.size(), 4u);
  EXPECT_EQ(decoder.inputSize(), 12);
  EXPECT_EQ(decoder.outputSize(), 3);
  EXPECT_EQ(decoder.parameterCount(), 24383u);
  // 95.2 KiB as float32, the paper's Table 1 figure.
  EXPECT_NEAR(decoder.parameterCount() * 4 / 1024.0, 95.2, 0.05);
  // 12x106 + 106x106 + 106x106 + 106x3 multiply-adds.
  EXPECT_DOUBLE_EQ(decoder.flopsPerSample(), 2.0 * (12 * 106 + 2 * 106 * 106 + 106 * 3));
  EXPECT_NO_THROW(decoder.validate());
}

TEST(Mlp, ExportedDecoderEqualsTorchDecoder) {
  ModelConfig model;
  model.directionInputs = DirectionEncoding::Stereographic;  // the paper's 12 inputs
  model.planeFeatures = 0;
  RowMatrix in(300, 12);
  for (Eigen::Index i = 0; i < in.size(); ++i) in.data()[i] = std::sin(0.37f * i) * 1.5f;
  ReferenceDecoder ref = referenceDecoder(model, 42, in);
  EXPECT_EQ(ref.exported.parameterCount(), 24383u);
  RowMatrix ours = mlpForward(ref.exported, in);
  ASSERT_EQ(ours.rows(), ref.torchOutput.rows());
  ASSERT_EQ(ours.cols(), 3);
  float scale = ref.torchOutput.cwiseAbs().maxCoeff();
  EXPECT_GT(scale, 0.01f);
  EXPECT_LT((ours - ref.torchOutput).cwiseAbs().maxCoeff(), 1e-5f * std::max(1.0f, scale));
}

}  // namespace nbtf
