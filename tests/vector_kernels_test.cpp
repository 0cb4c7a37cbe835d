// The encoder layers' float vector kernels (model/kernels/vector_kernels.h): dot16 and axpy.
#include "model/kernels/vector_kernels.h"

#include <gtest/gtest.h>

#include <vector>

namespace nbtf::detail {
namespace {

TEST(VectorKernels, Dot16SumsTheProductsAtEveryLength) {
  for (int n : {0, 1, 15, 16, 17, 48, 100}) {
    std::vector<float> a(n), b(n);
    float expected = 0;  // small integers: exact in any order
    for (int i = 0; i < n; ++i) {
      a[i] = static_cast<float>(i % 7 - 3);
      b[i] = static_cast<float>(i % 5 - 2);
      expected += a[i] * b[i];
    }
    EXPECT_EQ(dot16(a.data(), b.data(), n), expected) << n;
  }
}

// 16 partial sums, lane i holding the terms i, i + 16, ...: a small term in one lane is not
// lost against a large one in another lane until the lanes are added.
TEST(VectorKernels, Dot16KeepsSixteenPartialSums) {
  std::vector<float> a(32, 0.0f), b(32, 1.0f);
  a[0] = 1e8f, a[16] = -1e8f;  // lane 0 cancels exactly
  a[1] = 1.0f;                 // lane 1
  EXPECT_EQ(dot16(a.data(), b.data(), 32), 1.0f);
  // The plain left-to-right sum would lose the 1 against 1e8 before the cancellation.
  float plain = 0;
  for (int i : {0, 1, 16}) plain += a[i] * b[i];
  EXPECT_EQ(plain, 0.0f);
}

TEST(VectorKernels, AxpyAddsAScaledVector) {
  for (int n : {0, 1, 17, 64}) {
    std::vector<float> x(n), y(n), expected(n);
    for (int i = 0; i < n; ++i) {
      x[i] = static_cast<float>(i - 8);
      y[i] = static_cast<float>(2 * i);
      expected[i] = y[i] + 0.5f * x[i];
    }
    axpy(0.5f, x.data(), y.data(), n);
    EXPECT_EQ(y, expected) << n;
  }
}

}  // namespace
}  // namespace nbtf::detail
