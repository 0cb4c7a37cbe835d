#include "model/kernels/dense_kernels.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "dense_kernels_fixtures.h"

namespace nbtf::detail {
namespace {

using kernel_test::randomValues;
using kernel_test::relativeError;
using kernel_test::Shape;

// Shapes that cover the register blocks' row tails (n not a multiple of the block), every
// panel width (1 to 4 vectors), several panels (cols > 64), an unaligned row stride, and
// sums deeper than one slice of the product (k > 48).
const Shape kShapes[] = {{512, 107, 112, 112}, {7, 5, 16, 5},   {13, 3, 32, 3},    {1, 1, 48, 1},
                         {11, 20, 64, 21},     {9, 17, 80, 17}, {10, 33, 96, 40},  {5, 40, 208, 40},
                         {4, 9, 128, 9},       {0, 4, 16, 4}};

}  // namespace

// Every build of the kernels this CPU runs: AVX-512 register blocks, AVX2 + FMA blocks, the
// narrow path of every other CPU (a build the CPU cannot run is skipped, and says so).
class DenseKernels : public testing::TestWithParam<DenseKernelTier> {
 protected:
  void SetUp() override {
    if (!denseKernelTierSupported(GetParam())) GTEST_SKIP() << "this CPU cannot run this build";
    setDenseKernelTier(GetParam());
  }
  void TearDown() override { setDenseKernelTier(DenseKernelTier::Auto); }
};
INSTANTIATE_TEST_SUITE_P(Builds, DenseKernels,
                         testing::Values(DenseKernelTier::Auto, DenseKernelTier::Narrow, DenseKernelTier::Mid,
                                         DenseKernelTier::Wide),
                         [](const testing::TestParamInfo<DenseKernelTier>& p) {
                           switch (p.param) {
                             case DenseKernelTier::Narrow: return "Narrow";
                             case DenseKernelTier::Mid: return "Avx2Fma";
                             case DenseKernelTier::Wide: return "Avx512";
                             default: return "Native";
                           }
                         });

TEST_P(DenseKernels, ProductsMatchADoubleReference) {
  std::mt19937 rng(7);
  for (const Shape& s : kShapes) {
    SCOPED_TRACE(testing::Message() << "n " << s.n << " k " << s.k << " cols " << s.cols);
    AlignedFloats b, h, y;
    b.assign(static_cast<std::size_t>(s.k) * s.cols, 0.0f);
    h.assign(static_cast<std::size_t>(s.n) * s.cols, 0.0f);
    y.assign(h.size(), 0.0f);
    std::vector<float> x = randomValues(static_cast<std::size_t>(s.n) * s.ld + s.k, rng);
    std::vector<float> bv = randomValues(b.size(), rng), hv = randomValues(h.size(), rng);
    std::copy(bv.begin(), bv.end(), b.data());
    std::copy(hv.begin(), hv.end(), h.data());
    std::vector<double> plain(h.size()), relu(h.size()), masked(h.size());
    for (int r = 0; r < s.n; ++r)
      for (int j = 0; j < s.cols; ++j) {
        double sum = 0;
        for (int q = 0; q < s.k; ++q) sum += static_cast<double>(x[r * s.ld + q]) * bv[q * s.cols + j];
        plain[r * s.cols + j] = sum;
        relu[r * s.cols + j] = std::max(0.0, sum);
        masked[r * s.cols + j] = hv[r * s.cols + j] > 0 ? sum : 0.0;
      }
    product(s.n, s.k, x.data(), s.ld, b.data(), s.cols, y.data());
    EXPECT_LT(relativeError(y.data(), plain), 1e-6);
    productRelu(s.n, s.k, x.data(), s.ld, b.data(), s.cols, y.data());
    EXPECT_LT(relativeError(y.data(), relu), 1e-6);
    productMasked(s.n, s.k, x.data(), s.ld, b.data(), s.cols, h.data(), y.data());
    EXPECT_LT(relativeError(y.data(), masked), 1e-6);
    // The mask is exact: no value leaks through where h <= 0.
    for (std::size_t i = 0; i < hv.size(); ++i)
      if (hv[i] <= 0) ASSERT_EQ(y.data()[i], 0.0f);
  }
}

TEST_P(DenseKernels, AccumulateOuterAddsToTheGradient) {
  std::mt19937 rng(8);
  for (const Shape& s : kShapes) {
    const int m = s.k;  // gradient rows
    SCOPED_TRACE(testing::Message() << "n " << s.n << " m " << m << " cols " << s.cols);
    AlignedFloats h, w;
    h.assign(static_cast<std::size_t>(s.n) * s.cols, 0.0f);
    w.assign(static_cast<std::size_t>(m) * s.cols, 0.0f);
    std::vector<float> g = randomValues(static_cast<std::size_t>(s.n) * s.ld + m, rng);
    std::vector<float> hv = randomValues(h.size(), rng), w0 = randomValues(w.size(), rng);
    std::copy(hv.begin(), hv.end(), h.data());
    std::copy(w0.begin(), w0.end(), w.data());
    std::vector<double> expected(w.size());
    for (int i = 0; i < m; ++i)
      for (int j = 0; j < s.cols; ++j) {
        double sum = w0[i * s.cols + j];
        for (int r = 0; r < s.n; ++r) sum += static_cast<double>(g[r * s.ld + i]) * hv[r * s.cols + j];
        expected[i * s.cols + j] = sum;
      }
    accumulateOuter(s.n, m, g.data(), s.ld, h.data(), s.cols, w.data());
    EXPECT_LT(relativeError(w.data(), expected), 1e-6);
  }
}

TEST(DenseKernelsRowDots, MatchADoubleReference) {
  std::mt19937 rng(9);
  for (int cols : {16, 112, 208}) {
    const int n = 9, m = 3;
    std::vector<float> h = randomValues(static_cast<std::size_t>(n) * cols, rng), w = randomValues(m * cols, rng);
    std::vector<double> expected(n * m);
    for (int r = 0; r < n; ++r)
      for (int i = 0; i < m; ++i)
        for (int j = 0; j < cols; ++j) expected[r * m + i] += static_cast<double>(h[r * cols + j]) * w[i * cols + j];
    std::vector<float> out(n * m);
    rowDots(n, m, h.data(), cols, w.data(), out.data());
    EXPECT_LT(relativeError(out.data(), expected), 1e-6) << "cols " << cols;
  }
}

TEST(AlignedFloats, IsAlignedAndZeroed) {
  AlignedFloats a;
  for (std::size_t n : {1, 17, 1000}) {
    a.assign(n, 0.0f);
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(a.data()) % 64, 0u);
    EXPECT_EQ(a.size(), n);
    for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(a.data()[i], 0.0f);
    a.data()[n - 1] = 3;
  }
  EXPECT_EQ(paddedWidth(106 + 1), 112);
  EXPECT_EQ(paddedWidth(16), 16);
  EXPECT_EQ(paddedWidth(1), 16);
}

}  // namespace nbtf::detail
