// The bfloat16 operand kernels (model/kernels/dense_kernels_bf16.cpp): rounding, operand layouts and products, native and portable.
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

}  // namespace

// ---- bfloat16 operands (productBf16, accumulateOuterBf16).
TEST(Bf16, RoundsToNearestEven) {
  EXPECT_EQ(toBf16(1.0f), 0x3f80);
  EXPECT_EQ(toBf16(-2.0f), 0xc000);
  EXPECT_EQ(toBf16(1.0f + 1.0f / 256), 0x3f80);      // a tie: to the even 1.0
  EXPECT_EQ(toBf16(1.0f + 3.0f / 256), 0x3f82);      // a tie: to the even 1 + 2/128
  EXPECT_EQ(toBf16(1.0f + 1.5f / 256), 0x3f81);      // above the tie: up
  EXPECT_EQ(toBf16(1e-40f), 0x0000);                 // subnormal: zero, as the instruction reads it
  EXPECT_EQ(toBf16(-0.0f), 0x8000);
  EXPECT_TRUE(std::isnan(fromBf16(toBf16(std::nanf("")))));
  EXPECT_EQ(fromBf16(toBf16(0.3f)), 0.30078125f);    // 8 significant bits
  for (float v : {3.0f, -0.5f, 65536.0f, 1.0f / 1024}) EXPECT_EQ(fromBf16(toBf16(v)), v);
}

TEST(Bf16, RowPairsInterleaveConsecutiveRows) {
  const float src[] = {1, 2, 3, 4, 5, 6, 7, 8, 9};  // 3 rows x 2 columns, row stride 3
  Bf16 pairs[8];
  toBf16RowPairs(3, 2, src, 3, pairs);
  const float expected[] = {1, 4, 2, 5, 7, 0, 8, 0};  // the odd last row pairs with zeros
  for (int i = 0; i < 8; ++i) EXPECT_EQ(fromBf16(pairs[i]), expected[i]) << i;
  Bf16 rows[8];
  toBf16Rows(2, 3, src, 3, rows, 4);
  const float expectedRows[] = {1, 2, 3, 0, 4, 5, 6, 0};
  for (int i = 0; i < 8; ++i) EXPECT_EQ(fromBf16(rows[i]), expectedRows[i]) << i;
}

// Both builds (the instruction where this CPU has it, the portable steps everywhere) against
// a double reference of the rounded operands, and against each other bit for bit.
class Bf16Products : public testing::TestWithParam<bool> {
 protected:
  void SetUp() override {
    if (!GetParam() && !bf16ProductsNative()) GTEST_SKIP() << "this CPU has no AVX-512 BF16";
    setBf16ProductsPortable(GetParam());
  }
  void TearDown() override { setBf16ProductsPortable(false); }
};
INSTANTIATE_TEST_SUITE_P(Builds, Bf16Products, testing::Values(false, true),
                         [](const testing::TestParamInfo<bool>& p) { return p.param ? "Portable" : "Avx512Bf16"; });

// Shapes with even sums (k), row tails of every register block, every panel width, several panels.
const Shape kBf16Shapes[] = {{512, 108, 112, 112}, {7, 6, 16, 6}, {13, 4, 32, 4}, {1, 2, 48, 2},
                             {11, 20, 64, 22},     {9, 18, 80, 18}, {10, 34, 96, 40}, {5, 40, 208, 40}, {0, 4, 16, 4}};

std::vector<float> roundedValues(std::size_t n, std::mt19937& rng) {
  std::vector<float> v = randomValues(n, rng);
  for (float& x : v) x = fromBf16(toBf16(x));
  return v;
}

TEST_P(Bf16Products, ProductsMatchADoubleReference) {
  std::mt19937 rng(17);
  for (const Shape& s : kBf16Shapes) {
    SCOPED_TRACE(testing::Message() << "n " << s.n << " k " << s.k << " cols " << s.cols);
    const std::vector<float> x = roundedValues(static_cast<std::size_t>(s.n) * s.ld, rng);
    const std::vector<float> b = roundedValues(static_cast<std::size_t>(s.k) * s.cols, rng);
    const std::vector<float> h = randomValues(static_cast<std::size_t>(s.n) * s.cols, rng);
    std::vector<Bf16> xb(x.size() + 2), bp(b.size() + 2 * s.cols);
    toBf16Rows(s.n, s.ld, x.data(), s.ld, xb.data(), s.ld);
    toBf16RowPairs(s.k, s.cols, b.data(), s.cols, bp.data());
    std::vector<double> plain(h.size());
    for (int r = 0; r < s.n; ++r)
      for (int j = 0; j < s.cols; ++j)
        for (int q = 0; q < s.k; ++q) plain[r * s.cols + j] += static_cast<double>(x[r * s.ld + q]) * b[q * s.cols + j];
    std::vector<float> y(h.size());
    for (Bf16Epilogue e : {Bf16Epilogue::None, Bf16Epilogue::Relu, Bf16Epilogue::Mask}) {
      std::vector<double> expected = plain;
      for (std::size_t i = 0; i < expected.size(); ++i)
        if (e == Bf16Epilogue::Relu) expected[i] = std::max(0.0, expected[i]);
        else if (e == Bf16Epilogue::Mask && h[i] <= 0) expected[i] = 0;
      productBf16(e, s.n, s.k, xb.data(), s.ld, bp.data(), s.cols, e == Bf16Epilogue::Mask ? h.data() : nullptr, y.data());
      EXPECT_LT(relativeError(y.data(), expected), 1e-6) << static_cast<int>(e);
      if (e == Bf16Epilogue::Mask)
        for (std::size_t i = 0; i < h.size(); ++i)
          if (h[i] <= 0) ASSERT_EQ(y[i], 0.0f);
      // The other build gives the same bits.
      if (bf16ProductsNative()) {
        std::vector<float> other(y.size());
        setBf16ProductsPortable(!GetParam());
        productBf16(e, s.n, s.k, xb.data(), s.ld, bp.data(), s.cols, e == Bf16Epilogue::Mask ? h.data() : nullptr,
                    other.data());
        setBf16ProductsPortable(GetParam());
        EXPECT_EQ(std::memcmp(y.data(), other.data(), y.size() * sizeof(float)), 0);
      }
    }
  }
}

TEST_P(Bf16Products, ConversionsMatchTheScalarRounding) {
  std::mt19937 rng(19);
  const int n = 5, cols = 37, lds = 40;  // an odd row count, a column tail, a row stride
  std::vector<float> src = randomValues(static_cast<std::size_t>(n) * lds, rng);
  const float special[] = {0.0f, -0.0f, 1e-40f, -1e-40f, std::nanf(""), INFINITY, -INFINITY, 1.0f + 1.0f / 256,
                           1.0f + 3.0f / 256, 3.4e38f, -1.17549435e-38f};
  std::copy(std::begin(special), std::end(special), src.begin() + 3);
  std::vector<Bf16> rows(static_cast<std::size_t>(n) * 48, 0xffff), pairs(static_cast<std::size_t>(n + 1) * cols, 0xffff);
  toBf16Rows(n, cols, src.data(), lds, rows.data(), 48);
  toBf16RowPairs(n, cols, src.data(), lds, pairs.data());
  for (int r = 0; r < n; ++r)
    for (int j = 0; j < 48; ++j) {
      const Bf16 expected = j < cols ? toBf16(src[r * lds + j]) : Bf16{0};
      ASSERT_EQ(rows[r * 48 + j], expected) << r << " " << j;
      if (j < cols) ASSERT_EQ(pairs[(r / 2 * cols + j) * 2 + r % 2], expected) << r << " " << j;
    }
  for (int j = 0; j < cols; ++j) ASSERT_EQ(pairs[(n / 2 * cols + j) * 2 + 1], 0) << j;
}

TEST_P(Bf16Products, AccumulateOuterAddsToTheGradient) {
  std::mt19937 rng(18);
  for (const Shape& s : kBf16Shapes) {
    const int m = s.k, n = s.n + 1;  // odd and even row counts
    SCOPED_TRACE(testing::Message() << "n " << n << " m " << m << " cols " << s.cols);
    const std::vector<float> g = roundedValues(static_cast<std::size_t>(n) * s.ld, rng);
    const std::vector<float> h = roundedValues(static_cast<std::size_t>(n) * s.cols, rng);
    const std::vector<float> w0 = randomValues(static_cast<std::size_t>(m) * s.cols, rng);
    std::vector<Bf16> gp(static_cast<std::size_t>(n + 1) * s.ld), hp(static_cast<std::size_t>(n + 1) * s.cols);
    toBf16RowPairs(n, s.ld, g.data(), s.ld, gp.data());
    toBf16RowPairs(n, s.cols, h.data(), s.cols, hp.data());
    std::vector<double> expected(w0.begin(), w0.end());
    for (int i = 0; i < m; ++i)
      for (int j = 0; j < s.cols; ++j)
        for (int r = 0; r < n; ++r) expected[i * s.cols + j] += static_cast<double>(g[r * s.ld + i]) * h[r * s.cols + j];
    std::vector<float> w = w0;
    accumulateOuterBf16(n, m, gp.data(), s.ld, hp.data(), s.cols, w.data());
    EXPECT_LT(relativeError(w.data(), expected), 1e-6);
    if (bf16ProductsNative()) {
      std::vector<float> other = w0;
      setBf16ProductsPortable(!GetParam());
      accumulateOuterBf16(n, m, gp.data(), s.ld, hp.data(), s.cols, other.data());
      setBf16ProductsPortable(GetParam());
      EXPECT_EQ(std::memcmp(w.data(), other.data(), w.size() * sizeof(float)), 0);
    }
  }
}

}  // namespace nbtf::detail
