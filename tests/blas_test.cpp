// Float products through the system BLAS (linalg/blas.h): against Eigen, in every transpose, and the same on any thread count.
#include "linalg/blas.h"

#include <gtest/gtest.h>

#include <cmath>

#include "util/error.h"
#include "util/parallel.h"

namespace nbtf {
namespace {

// Small integers: every product is exact in float, so BLAS and Eigen agree bit for bit.
MatrixXfCol integerMatrix(Eigen::Index rows, Eigen::Index cols, int seed) {
  MatrixXfCol m(rows, cols);
  for (Eigen::Index j = 0; j < cols; ++j)
    for (Eigen::Index i = 0; i < rows; ++i) m(i, j) = static_cast<float>((i * 3 + j * 7 + seed) % 9 - 4);
  return m;
}

TEST(Blas, MultiplyEqualsEigenWithAndWithoutTransposeAcrossSlices) {
  const MatrixXfCol a = integerMatrix(1500, 20, 1), b = integerMatrix(20, 7, 2);  // 1500 rows: two slices
  MatrixXfCol c;
  blasMultiply(a, false, b, c);
  ASSERT_EQ(c.rows(), 1500);
  ASSERT_EQ(c.cols(), 7);
  EXPECT_TRUE(c == a * b);
  const MatrixXfCol at = integerMatrix(20, 1100, 3);  // transposed: slices of 512 rows
  blasMultiply(at, true, b, c);
  ASSERT_EQ(c.rows(), 1100);
  EXPECT_TRUE(c == at.transpose() * b);
}

TEST(Blas, EmptyAndMismatchedShapes) {
  MatrixXfCol c(3, 3);
  blasMultiply(MatrixXfCol(4, 0), false, MatrixXfCol(0, 5), c);  // empty inner size: zeros
  ASSERT_EQ(c.rows(), 4);
  ASSERT_EQ(c.cols(), 5);
  EXPECT_TRUE(c.isZero(0));
  blasMultiply(MatrixXfCol(0, 3), false, integerMatrix(3, 2, 0), c);
  EXPECT_EQ(c.rows(), 0);
  EXPECT_EQ(c.cols(), 2);
  EXPECT_THROW(blasMultiply(integerMatrix(4, 3, 0), false, integerMatrix(4, 2, 0), c), Error);
  EXPECT_THROW(blasMultiply(integerMatrix(4, 3, 0), true, integerMatrix(3, 2, 0), c), Error);
}

TEST(Blas, ResultsDoNotDependOnTheThreadCount) {
  MatrixXfCol a(3000, 33), b(33, 9);
  for (Eigen::Index i = 0; i < a.size(); ++i) a.data()[i] = std::sin(0.37f * static_cast<float>(i));
  for (Eigen::Index i = 0; i < b.size(); ++i) b.data()[i] = std::cos(0.11f * static_cast<float>(i));
  MatrixXfCol one, two;
  setThreadCount(1);
  blasMultiply(a, false, b, one);
  setThreadCount(2);
  blasMultiply(a, false, b, two);
  setThreadCount(0);
  EXPECT_TRUE(one == two);
}

// gemmOnThisThread: column-major BLAS conventions, both transposes, and accumulation.
TEST(Blas, GemmOnThisThreadTransposesAndAccumulates) {
  const MatrixXfCol a = integerMatrix(5, 4, 4), b = integerMatrix(4, 3, 5);
  MatrixXfCol c(5, 3);
  gemmOnThisThread(false, false, 5, 3, 4, a.data(), 5, b.data(), 4, c.data(), 5);
  EXPECT_TRUE(c == a * b);
  const MatrixXfCol at = a.transpose(), bt = b.transpose();
  MatrixXfCol d(5, 3);
  gemmOnThisThread(true, true, 5, 3, 4, at.data(), 4, bt.data(), 3, d.data(), 5);
  EXPECT_TRUE(d == a * b);
  gemmOnThisThread(false, false, 5, 3, 4, a.data(), 5, b.data(), 4, d.data(), 5, /*accumulate=*/true);
  EXPECT_TRUE(d == 2 * (a * b));
}

}  // namespace
}  // namespace nbtf
