// Torch-free kernels of the fused Conv1d(kernel 3, padding 1) + MaxPool1d(3) (conv_pool.cpp),
// in a phase layout: a signal's zero-padded row xpad (xpad[i] = x[i - 1]) is kept as three rows
// P_k[p] = xpad[3p + k]. Then convolution position 3p + j reads P_{j + t}[p] (t the tap; k = 3, 4
// mean P_0, P_1 at p + 1), so the three positions of a pooling window sit in the same lane of
// three vectors: pooling and its gradient are lane-wise, and the convolution, its transpose and
// its weight gradient are register-blocked FMAs over 16 windows at a time with no shuffles.
#pragma once
#include <cstdint>

namespace nbtf::detail::phases {

constexpr int kLanes = 16;
// Destination channel counts of convolve() must be a multiple of this (pad with zero weights).
constexpr int kChannelBlock = 4;

// Floats per phase row for a signal of `length`: windows p <= length / 3 (the transpose
// needs one past the last pooled window), rounded up to whole vectors, plus one vector for
// the loads at p + 1. A multiple of kLanes.
int rowStride(int length);
// Vectors of kLanes windows that cover `windows` windows.
inline int vectorsFor(int windows) { return (windows + kLanes - 1) / kLanes; }

// x [length] -> its padded phase rows phases[k * stride + p] = xpad[3p + k], zero past the end.
void split(const float* x, int length, int stride, float* phases);

// dst[(d * 3 + j) * dstStride + p] = bias[d] + sum_{s, t} coef[(d * srcChannels + s) * 3 + t] * P^s_{j + t}[p]
// for d < dstChannels (a multiple of kChannelBlock), j < 3, p < 16 * vectors; src holds
// srcChannels padded phase rows ([s][k][stride]); bias may be null (0). Callers go a chunk of
// windows at a time (src and dst advanced) so that dst stays in L1 for the next pass.
// Forward: coef = weight, dst row j = convolution at 3p + j. Input gradient: src = the
// convolution's gradient in phase rows, coef[c][o][t] = weight[o][c][2 - t], dst row j = dx at 3p + j.
void convolve(const float* src, int srcChannels, int stride, const float* coef, const float* bias, int dstChannels,
              int vectors, float* dst, int dstStride);

// Max over the three rows of a window: y[p], which[p] = the winning row, for p < pooled.
// torch's rule: a later value wins only if strictly greater (or NaN).
void pool(const float* conv, int stride, int pooled, float* y, std::uint8_t* which);

// The convolution's gradient (gy[p] at position 3p + which[p], else 0) as padded phase rows
// (like split), zero past the end. Returns the sum of gy (the bias gradient).
float unpool(const float* gy, const std::uint8_t* which, int pooled, int stride, float* phases);

// x[m] = rows[(m % 3) * stride + m / 3] for m < length: rows of convolve() back to a signal.
void merge(const float* rows, int stride, int length, float* x);

// gw[(o * inChannels + c) * 3 + t] = sum over positions l of gconv_o[l] * xpad_c[l + t], for
// o < outChannels (a multiple of kChannelBlock), windows p < 16 * vectors. g: unpool's rows
// per output channel, x: split's rows per input channel.
void weightGradient(const float* g, int outChannels, const float* x, int inChannels, int stride, int vectors,
                    float* gw);

}  // namespace nbtf::detail::phases
