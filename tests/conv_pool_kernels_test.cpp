// The torch-free conv + pool kernels in phase rows (model/kernels/conv_pool_kernels.h) against direct loops over the padded signal.
#include "model/kernels/conv_pool_kernels.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

namespace nbtf::detail::phases {
namespace {

// Small integers: every sum below is exact in float, whatever its order.
std::vector<float> integerSignal(int n, int seed) {
  std::vector<float> v(n);
  for (int i = 0; i < n; ++i) v[i] = static_cast<float>((i * 7 + seed * 5) % 11 - 5);
  return v;
}

// The zero-padded signal: xpad[i] = x[i - 1] for 1 <= i <= length, else 0.
float padded(const std::vector<float>& x, int i) { return i >= 1 && i <= static_cast<int>(x.size()) ? x[i - 1] : 0.0f; }

std::vector<float> splitRows(const std::vector<float>& x, int stride) {
  std::vector<float> rows(3 * static_cast<std::size_t>(stride), -99.0f);
  split(x.data(), static_cast<int>(x.size()), stride, rows.data());
  return rows;
}

}  // namespace

TEST(ConvPoolKernels, RowStrideCoversEveryWindowPlusOneVector) {
  EXPECT_EQ(rowStride(3), 32);   // windows 0..1: one vector, plus one
  EXPECT_EQ(rowStride(30), 32);  // 11 windows
  EXPECT_EQ(rowStride(47), 32);  // 16 windows
  EXPECT_EQ(rowStride(48), 48);  // 17 windows: two vectors
  EXPECT_EQ(rowStride(6561), (vectorsFor(2188) + 1) * kLanes);
  for (int length : {1, 2, 3, 4, 46, 47, 48, 100, 245}) {
    EXPECT_EQ(rowStride(length) % kLanes, 0) << length;
    EXPECT_GE(rowStride(length), kLanes * vectorsFor(length / 3 + 1) + 1) << length;
  }
  EXPECT_EQ(vectorsFor(0), 0);
  EXPECT_EQ(vectorsFor(1), 1);
  EXPECT_EQ(vectorsFor(16), 1);
  EXPECT_EQ(vectorsFor(17), 2);
}

TEST(ConvPoolKernels, SplitAndMergeAreThePaddedSignalsPhaseRows) {
  for (int length : {1, 2, 3, 8, 30, 31, 47, 100}) {
    SCOPED_TRACE(length);
    const std::vector<float> x = integerSignal(length, length);
    const int stride = rowStride(length);
    const std::vector<float> rows = splitRows(x, stride);
    for (int k = 0; k < 3; ++k)
      for (int p = 0; p < stride; ++p) ASSERT_EQ(rows[k * stride + p], padded(x, 3 * p + k)) << k << " " << p;
    // Rows holding the signal itself (not padded) merge back into it.
    std::vector<float> plain(3 * static_cast<std::size_t>(stride), 0.0f);
    for (int m = 0; m < length; ++m) plain[(m % 3) * stride + m / 3] = x[m];
    std::vector<float> back(length, -1.0f);
    merge(plain.data(), stride, length, back.data());
    EXPECT_EQ(back, x);
  }
}

// convolve(): row j of destination channel d at window p is the convolution (kernel 3, padding
// 1) at position 3p + j; both channel block sizes (8 and 4) and a bias.
TEST(ConvPoolKernels, ConvolveIsTheConvolutionAtEveryPosition) {
  const int length = 50, in = 2, stride = rowStride(length), vectors = vectorsFor(length / 3 + 1);
  std::vector<std::vector<float>> x(in);
  std::vector<float> src;
  for (int s = 0; s < in; ++s) {
    x[s] = integerSignal(length, s + 1);
    const std::vector<float> rows = splitRows(x[s], stride);
    src.insert(src.end(), rows.begin(), rows.end());
  }
  for (int out : {4, 12}) {
    SCOPED_TRACE(out);
    const std::vector<float> weight = integerSignal(out * in * 3, 3), bias = integerSignal(out, 4);
    const int dstStride = vectors * kLanes;
    std::vector<float> dst(static_cast<std::size_t>(out) * 3 * dstStride, -99.0f);
    convolve(src.data(), in, stride, weight.data(), bias.data(), out, vectors, dst.data(), dstStride);
    for (int d = 0; d < out; ++d)
      for (int j = 0; j < 3; ++j)
        for (int p = 0; p < vectors * kLanes; ++p) {
          float expected = bias[d];
          for (int s = 0; s < in; ++s)
            for (int t = 0; t < 3; ++t) expected += weight[(d * in + s) * 3 + t] * padded(x[s], 3 * p + j + t);
          ASSERT_EQ(dst[(d * 3 + j) * dstStride + p], expected) << d << " " << j << " " << p;
        }
    // Without a bias: the same less the bias.
    std::vector<float> noBias(dst.size());
    convolve(src.data(), in, stride, weight.data(), nullptr, out, vectors, noBias.data(), dstStride);
    for (int d = 0; d < out; ++d)
      for (int i = 0; i < 3 * dstStride; ++i)
        ASSERT_EQ(noBias[d * 3 * dstStride + i], dst[d * 3 * dstStride + i] - bias[d]);
  }
}

// pool(): the first maximum wins ties, a NaN wins; unpool() puts each window's gradient back at
// its winner in split()'s layout and returns their sum.
TEST(ConvPoolKernels, PoolTakesTheFirstMaximumAndUnpoolRoutesTheGradientBack) {
  const int stride = 32, pooled = 5;
  std::vector<float> conv(3 * stride, 0.0f);
  const float windows[pooled][3] = {{1, 2, 3}, {3, 2, 1}, {2, 2, 2}, {0, 5, 5}, {1, NAN, 0}};
  for (int p = 0; p < pooled; ++p)
    for (int j = 0; j < 3; ++j) conv[j * stride + p] = windows[p][j];
  std::vector<float> y(pooled);
  std::vector<std::uint8_t> which(pooled);
  pool(conv.data(), stride, pooled, y.data(), which.data());
  EXPECT_EQ(std::vector<int>(which.begin(), which.end()), (std::vector<int>{2, 0, 0, 1, 1}));
  EXPECT_EQ(y[0], 3);
  EXPECT_EQ(y[1], 3);
  EXPECT_EQ(y[2], 2);
  EXPECT_EQ(y[3], 5);
  EXPECT_TRUE(std::isnan(y[4]));

  const std::vector<float> gy = {1, 2, 3, 4, 5};
  std::vector<float> rows(3 * stride, -99.0f);
  EXPECT_EQ(unpool(gy.data(), which.data(), pooled, stride, rows.data()), 15.0f);
  // The convolution's gradient: gy[p] at position 3p + which[p], else 0; in phase rows.
  std::vector<float> gconv(3 * pooled, 0.0f);
  for (int p = 0; p < pooled; ++p) gconv[3 * p + which[p]] = gy[p];
  for (int k = 0; k < 3; ++k)
    for (int p = 0; p < stride; ++p) ASSERT_EQ(rows[k * stride + p], padded(gconv, 3 * p + k)) << k << " " << p;
}

TEST(ConvPoolKernels, WeightGradientSumsTheGradientTimesThePaddedInput) {
  const int length = 40, in = 3, stride = rowStride(length), vectors = vectorsFor(length / 3 + 1);
  for (int out : {4, 8, 12}) {
    SCOPED_TRACE(out);
    std::vector<std::vector<float>> x(in), g(out);
    std::vector<float> xRows, gRows;
    for (int c = 0; c < in; ++c) {
      x[c] = integerSignal(length, c + 2);
      const std::vector<float> rows = splitRows(x[c], stride);
      xRows.insert(xRows.end(), rows.begin(), rows.end());
    }
    for (int o = 0; o < out; ++o) {
      g[o] = integerSignal(length, o + 7);
      const std::vector<float> rows = splitRows(g[o], stride);
      gRows.insert(gRows.end(), rows.begin(), rows.end());
    }
    std::vector<float> gw(static_cast<std::size_t>(out) * in * 3, -99.0f);
    weightGradient(gRows.data(), out, xRows.data(), in, stride, vectors, gw.data());
    for (int o = 0; o < out; ++o)
      for (int c = 0; c < in; ++c)
        for (int t = 0; t < 3; ++t) {
          float expected = 0;
          for (int l = 0; l < length; ++l) expected += g[o][l] * padded(x[c], l + t);
          EXPECT_EQ(gw[(o * in + c) * 3 + t], expected) << o << " " << c << " " << t;
        }
  }
}

}  // namespace nbtf::detail::phases
