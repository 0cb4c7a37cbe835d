#include "preprocess/abrdf_matrix.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "util/error.h"
#include "util/half.h"
#include "util/parallel.h"
#include "util/progress.h"

namespace nbtf {
namespace {

// A 3 x 2 texel stack of 2 lights x 2 views in half floats, every value distinct.
BtfStack smallStack() {
  std::vector<Direction> lights = {{0, 0}, {30, 90}}, views = {{0, 0}, {45, 180}};
  BtfStack stack(lights, views, 3, 2, SampleType::Half);
  for (int image = 0; image < stack.numImages(); ++image) {
    std::vector<float> rgb(stack.numTexels() * 3);
    for (int t = 0; t < stack.numTexels(); ++t)
      for (int c = 0; c < 3; ++c) rgb[3 * t + c] = 0.125f * (1 + image) + 0.25f * t + 0.0625f * c;
    stack.setImageLinear(image, rgb.data());
  }
  return stack;
}

MatrixXfCol randomPositive(int rows, int cols, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 2.0f);
  MatrixXfCol x(rows, cols);
  for (int c = 0; c < cols; ++c)
    for (int r = 0; r < rows; ++r) x(r, c) = u(rng) * (1 + c % 3);  // different scales per dimension
  return x;
}

class AbrdfMatrixTest : public ::testing::Test {
 protected:
  void SetUp() override { Progress::setQuiet(true); }
};

TEST_F(AbrdfMatrixTest, RowsAreTheStacksAbrdfs) {
  BtfStack stack = smallStack();
  MatrixXfCol x = abrdfMatrix(stack, false);
  ASSERT_EQ(x.rows(), 6);
  ASSERT_EQ(x.cols(), 12);
  for (int t = 0; t < stack.numTexels(); ++t) {
    std::vector<float> abrdf = stack.abrdfLinear(t);
    for (int d = 0; d < 12; ++d) EXPECT_EQ(x(t, d), abrdf[d]) << "texel " << t << " dim " << d;
  }
  // Column 3 * image + channel: image 2, texel 4, channel 1.
  EXPECT_FLOAT_EQ(x(4, 3 * 2 + 1), 0.125f * 3 + 0.25f * 4 + 0.0625f);
}

TEST_F(AbrdfMatrixTest, StandardizedDimensionsHaveMeanZeroAndUnitStd) {
  MatrixXfCol x = randomPositive(500, 9, 1);
  MatrixXfCol original = x;
  Standardization s = standardizeInPlace(x);
  for (int d = 0; d < x.cols(); ++d) {
    double mean = x.col(d).cast<double>().mean();
    double var = (x.col(d).cast<double>().array() - mean).square().mean();
    EXPECT_NEAR(mean, 0.0, 1e-5);
    EXPECT_NEAR(var, 1.0, 1e-4);
    // The statistics are those of log(x + 1).
    double logMean = original.col(d).cast<double>().array().log1p().mean();
    EXPECT_NEAR(s.mean[d], logMean, 1e-5);
  }
}

TEST_F(AbrdfMatrixTest, TinyValuesKeepTheirLogPrecision) {
  // Dark pixels: linear values around 1e-6, where log(1 + x) computed naively in float
  // would be off by percents (1 + x rounds away most of x).
  MatrixXfCol x(400, 2);
  for (int t = 0; t < 400; ++t) x(t, 0) = 1e-7f * (1 + t % 37), x(t, 1) = 0.5f + 1e-3f * (t % 11);
  MatrixXfCol original = x;
  Standardization s = standardizeInPlace(x);
  for (int d = 0; d < 2; ++d) {
    double mean = original.col(d).cast<double>().array().log1p().mean();
    EXPECT_NEAR(s.mean[d], mean, 1e-5 * mean) << "dimension " << d;
  }
  MatrixXfCol back = x;
  s.invert(back);
  EXPECT_NEAR(back(36, 0), original(36, 0), 1e-3 * original(36, 0));
}

// log1pRun looks halves up in a table: the same bits as the formula, for every half >= 0,
// and other values (not halves, negative, -0) still computed.
TEST_F(AbrdfMatrixTest, Log1pOfHalvesIsTheFormulaBitForBit) {
  auto formula = [](float x) {
    const float u = x + 1.0f;
    return u == 1.0f ? x : std::log(u) * (x / (u - 1.0f));
  };
  std::vector<float> values;
  for (std::uint32_t h = 0; h < 0x7C00; ++h) values.push_back(halfToFloat(static_cast<std::uint16_t>(h)));
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> any(-0.99f, 70000.0f);
  for (int i = 0; i < 100000; ++i) values.push_back(any(rng));
  for (float v : {-0.0f, 1e-30f, 3e-8f, 65504.0f, 65505.0f, 1e30f}) values.push_back(v);
  std::vector<float> logs = values;
  log1pRun(logs.data(), static_cast<Eigen::Index>(logs.size()));
  int halves = 0;
  for (std::size_t i = 0; i < values.size(); ++i) {
    const float expected = formula(values[i]);
    ASSERT_EQ(std::memcmp(&logs[i], &expected, 4), 0) << values[i] << ": " << logs[i] << " vs " << expected;
    halves += roundToHalf(values[i]) == values[i];
  }
  EXPECT_GE(halves, 0x7C00);
}

TEST_F(AbrdfMatrixTest, ConstantDimensionsBecomeZeroNotNan) {
  MatrixXfCol x = randomPositive(100, 4, 2);
  x.col(1).setConstant(0.3f);  // a constant pixel
  x.col(2).setZero();          // a black pixel (shadowed in every texel)
  Standardization s = standardizeInPlace(x);
  EXPECT_EQ(s.stddev[1], 0.0f);
  EXPECT_EQ(s.stddev[2], 0.0f);
  EXPECT_NEAR(s.mean[1], std::log1p(0.3f), 1e-6);
  EXPECT_TRUE(x.allFinite());
  EXPECT_TRUE((x.col(1).array() == 0).all());
  EXPECT_TRUE((x.col(2).array() == 0).all());
  EXPECT_GT(s.stddev[0], 0.0f);
}

TEST_F(AbrdfMatrixTest, InvertRoundTripsTheLinearValues) {
  MatrixXfCol x = randomPositive(300, 6, 3);
  x.col(4).setConstant(0.7f);
  MatrixXfCol original = x;
  Standardization s = standardizeInPlace(x);
  s.invert(x);
  for (int d = 0; d < x.cols(); ++d)
    for (int t = 0; t < x.rows(); ++t) ASSERT_NEAR(x(t, d), original(t, d), 2e-6f * (1 + original(t, d)));
}

TEST_F(AbrdfMatrixTest, ApplyReproducesTheFittedTransformOnOtherData) {
  MatrixXfCol x = randomPositive(200, 5, 4);
  MatrixXfCol copy = x;
  Standardization s = standardizeInPlace(x);
  s.apply(copy);
  EXPECT_EQ(copy, x);  // bit for bit: the same arithmetic
  MatrixXfCol again = randomPositive(200, 5, 4);
  std::vector<float> row(5);
  for (int d = 0; d < 5; ++d) row[d] = again(17, d);
  s.applyRow(row.data());
  for (int d = 0; d < 5; ++d) EXPECT_FLOAT_EQ(row[d], x(17, d));
}

TEST_F(AbrdfMatrixTest, ApplyRejectsOtherWidths) {
  MatrixXfCol x = randomPositive(50, 5, 5);
  Standardization s = standardizeInPlace(x);
  MatrixXfCol other = randomPositive(50, 6, 5);
  EXPECT_THROW(s.apply(other), Error);
}

TEST_F(AbrdfMatrixTest, ValuesOutsideTheLogDomainAreNamed) {
  MatrixXfCol x = randomPositive(20, 6, 6);
  x(7, 4) = std::nanf("");
  try {
    standardizeInPlace(x);
    FAIL() << "NaN accepted";
  } catch (const Error& e) {
    std::string what = e.what();
    EXPECT_NE(what.find("texel 7"), std::string::npos) << what;
    EXPECT_NE(what.find("image 1, channel G"), std::string::npos) << what;
  }
  MatrixXfCol y = randomPositive(20, 6, 6);
  y(3, 0) = -1.0f;
  EXPECT_THROW(standardizeInPlace(y), Error);
}

TEST_F(AbrdfMatrixTest, SameResultOnAnyThreadCount) {
  MatrixXfCol a = randomPositive(400, 30, 7), b = a;
  setThreadCount(1);
  Standardization sa = standardizeInPlace(a);
  setThreadCount(2);
  Standardization sb = standardizeInPlace(b);
  setThreadCount(0);
  EXPECT_EQ(a, b);
  EXPECT_EQ(sa.mean, sb.mean);
}

TEST_F(AbrdfMatrixTest, AlphaIsTheGlobalMaximum) {
  BtfStack stack = smallStack();
  // Largest value: image 3, texel 5, channel 2.
  EXPECT_FLOAT_EQ(targetAlpha(stack), 0.125f * 4 + 0.25f * 5 + 0.0625f * 2);
  BtfStack black({{0, 0}}, {{0, 0}}, 2, 2, SampleType::Srgb8);
  black.source = "/data/black";
  try {
    targetAlpha(black);
    FAIL() << "all-zero stack accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/data/black"), std::string::npos);
  }
}

}  // namespace
}  // namespace nbtf
