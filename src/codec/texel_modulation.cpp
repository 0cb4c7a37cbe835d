#include "codec/texel_modulation.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "util/error.h"

namespace nbtf {

namespace {

// The range a column's codes cover: its 0.1% to 99.9% quantiles (min and max below 1000 texels),
// so that a few outlying texels do not coarsen the steps for all others.
std::pair<float, float> codeRange(std::vector<float> column) {
  const std::size_t texels = column.size(), cut = texels >= 1000 ? texels / 1000 : 0;
  std::nth_element(column.begin(), column.begin() + cut, column.end());
  const float lo = column[cut];
  std::nth_element(column.begin(), column.begin() + (texels - 1 - cut), column.end());
  return {lo, column[texels - 1 - cut]};
}

// Codes of `values` in [lo, lo + span]: round((v - lo) / span x levels), clamped to [0, levels].
void quantizeColumn(const std::vector<float>& values, double lo, double span, double levels, int column, int columns,
                    std::vector<std::uint16_t>& codes) {
  for (std::size_t t = 0; t < values.size(); ++t) {
    const double q = span > 0 ? std::round((values[t] - lo) / span * levels) : 0.0;
    codes[t * columns + column] = static_cast<std::uint16_t>(std::clamp(q, 0.0, levels));
  }
}

// Decorrelated codes (ModulationCodes::Decorrelated): per term, the rotation to the colour
// factor's principal axes and one step for its three rotated columns; then the code width the
// widest column needs, and the codes.
void quantizeDecorrelated(const std::vector<float>& coefficients, int terms, int bits, TexelModulation& m) {
  const int columns = terms * 3;
  const std::size_t texels = coefficients.size() / columns;
  const double levels = static_cast<double>((1u << bits) - 1);
  std::vector<std::vector<float>> rotated(columns, std::vector<float>(texels));
  std::vector<double> step(terms);
  std::vector<std::pair<float, float>> range(columns);
  int width = 1;
  for (int r = 0; r < terms; ++r) {
    double mean[3] = {0, 0, 0}, spans = 0;
    std::vector<float> channel(texels);
    for (int c = 0; c < 3; ++c) {
      for (std::size_t t = 0; t < texels; ++t) channel[t] = coefficients[t * columns + 3 * r + c];
      for (float v : channel) mean[c] += v;
      mean[c] /= static_cast<double>(texels);
      const auto [lo, hi] = codeRange(channel);
      spans += static_cast<double>(hi) - lo;
    }
    std::array<double, 9> covariance{};
    for (std::size_t t = 0; t < texels; ++t) {
      const float* x = &coefficients[t * columns + 3 * r];
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) covariance[3 * i + j] += (x[i] - mean[i]) * (x[j] - mean[j]);
    }
    const std::array<double, 9> axes = principalAxes3(covariance);
    for (int i = 0; i < 9; ++i) m.rotation[9 * r + i] = static_cast<float>(axes[i]);
    for (int k = 0; k < 3; ++k) {
      std::vector<float>& y = rotated[3 * r + k];
      for (std::size_t t = 0; t < texels; ++t) {  // y = R^T x with the stored (float) R
        const float* x = &coefficients[t * columns + 3 * r];
        double v = 0;
        for (int c = 0; c < 3; ++c) v += static_cast<double>(m.rotation[9 * r + 3 * c + k]) * x[c];
        y[t] = static_cast<float>(v);
      }
      range[3 * r + k] = codeRange(y);
    }
    // The step of `bits`-bit linear codes over the channels' mean span (a constant term codes as
    // 0), coarser only where the widest column would need more than 16 bits.
    double widest = 0;
    for (int k = 0; k < 3; ++k)
      widest = std::max(widest, static_cast<double>(range[3 * r + k].second) - range[3 * r + k].first);
    step[r] = std::max(spans > 0 ? spans / 3 / levels : 1.0, widest / 65535);
    while (width < 16 && std::ceil(widest / step[r]) > static_cast<double>((1u << width) - 1)) ++width;
  }
  m.bits = width;
  m.decorrelated = true;
  const double stored = static_cast<double>((1u << width) - 1);
  for (int q = 0; q < columns; ++q) {
    m.minimum[q] = range[q].first;
    m.maximum[q] = static_cast<float>(range[q].first + step[q / 3] * stored);
    // Quantize against the stored floats, as decoding reads them.
    quantizeColumn(rotated[q], m.minimum[q], static_cast<double>(m.maximum[q]) - m.minimum[q], stored, q, columns,
                   m.codes);
  }
}

}  // namespace

TexelModulation quantizeTexelCoefficients(const std::vector<float>& coefficients, int terms, int bits, int channels,
                                          ModulationCodes codes) {
  if (terms < 1 || terms > kMaxModulationTerms)
    throw Error("modulation terms must be in 1.." + std::to_string(kMaxModulationTerms) + ", got " +
                std::to_string(terms));
  if (bits < 1 || bits > 16) throw Error("modulation bits must be in 1..16, got " + std::to_string(bits));
  if (channels != 1 && channels != 3) throw Error("modulation channels must be 1 or 3, got " + std::to_string(channels));
  if (codes == ModulationCodes::Decorrelated && channels != 3)
    throw Error("decorrelated modulation codes need 3 channels, got " + std::to_string(channels));
  const int columns = terms * channels;
  if (coefficients.empty() || coefficients.size() % columns)
    throw Error("modulation: " + std::to_string(coefficients.size()) + " coefficients for " + std::to_string(terms) +
                " terms x " + std::to_string(channels) + " channels");
  const std::size_t texels = coefficients.size() / columns;
  for (std::size_t i = 0; i < coefficients.size(); ++i)
    if (!std::isfinite(coefficients[i]))
      throw Error("modulation: texel " + std::to_string(i / columns) + " has a non-finite coefficient in term " +
                  std::to_string(i % columns / channels));
  TexelModulation m;
  m.terms = terms;
  m.channels = channels;
  m.bits = bits;
  m.codes.resize(coefficients.size());
  if (codes == ModulationCodes::Decorrelated) {
    quantizeDecorrelated(coefficients, terms, bits, m);
    return m;
  }
  const double levels = static_cast<double>((1u << bits) - 1);
  std::vector<float> column(texels);
  for (int r = 0; r < columns; ++r) {
    for (std::size_t t = 0; t < texels; ++t) column[t] = coefficients[t * columns + r];
    const auto [lo, hi] = codeRange(column);
    m.minimum[r] = lo;
    m.maximum[r] = hi;
    quantizeColumn(column, lo, static_cast<double>(hi) - lo, levels, r, columns, m.codes);
  }
  return m;
}

std::array<double, 9> principalAxes3(std::array<double, 9> a) {
  std::array<double, 9> v{1, 0, 0, 0, 1, 0, 0, 0, 1};
  // Cyclic Jacobi: each rotation zeroes one off-diagonal pair; a few sweeps converge for 3 x 3.
  for (int sweep = 0; sweep < 64; ++sweep) {
    const double off = a[1] * a[1] + a[2] * a[2] + a[5] * a[5];
    const double diagonal = a[0] * a[0] + a[4] * a[4] + a[8] * a[8];
    if (!(off > 1e-30 * diagonal) || off == 0) break;
    for (auto [p, q] : {std::pair{0, 1}, std::pair{0, 2}, std::pair{1, 2}}) {
      const double apq = a[3 * p + q];
      if (apq == 0) continue;
      const double theta = (a[3 * q + q] - a[3 * p + p]) / (2 * apq);
      const double t = (theta >= 0 ? 1.0 : -1.0) / (std::fabs(theta) + std::sqrt(theta * theta + 1));
      const double c = 1 / std::sqrt(t * t + 1), s = t * c;
      for (int k = 0; k < 3; ++k) {  // columns p, q of A J
        const double akp = a[3 * k + p], akq = a[3 * k + q];
        a[3 * k + p] = c * akp - s * akq;
        a[3 * k + q] = s * akp + c * akq;
      }
      for (int k = 0; k < 3; ++k) {  // rows p, q of J^T (A J)
        const double apk = a[3 * p + k], aqk = a[3 * q + k];
        a[3 * p + k] = c * apk - s * aqk;
        a[3 * q + k] = s * apk + c * aqk;
      }
      for (int k = 0; k < 3; ++k) {  // V J
        const double vkp = v[3 * k + p], vkq = v[3 * k + q];
        v[3 * k + p] = c * vkp - s * vkq;
        v[3 * k + q] = s * vkp + c * vkq;
      }
    }
  }
  int order[3] = {0, 1, 2};
  std::stable_sort(order, order + 3, [&](int i, int j) { return a[4 * i] > a[4 * j]; });
  std::array<double, 9> axes{};
  for (int k = 0; k < 3; ++k) {
    const int j = order[k];
    int largest = 0;
    for (int i = 1; i < 3; ++i)
      if (std::fabs(v[3 * i + j]) > std::fabs(v[3 * largest + j])) largest = i;
    const double sign = v[3 * largest + j] < 0 ? -1.0 : 1.0;
    for (int i = 0; i < 3; ++i) axes[3 * i + k] = sign * v[3 * i + j];
  }
  return axes;
}

float dequantizeTexelCoefficient(const TexelModulation& m, int column, std::uint32_t code) {
  const double levels = static_cast<double>((1u << m.bits) - 1);
  const double lo = m.minimum[column], span = static_cast<double>(m.maximum[column]) - lo;
  return static_cast<float>(lo + span * (code / levels));
}

std::vector<float> orthonormalizeTexelCoefficients(std::vector<float> a, int terms,
                                                   const std::vector<std::int32_t>& ids, int clusters, int channels) {
  const std::size_t texels = ids.size();
  const int columns = terms * channels;
  if (terms < 1 || (channels != 1 && channels != 3) || a.size() != texels * columns)
    throw Error("modulation: " + std::to_string(a.size()) + " coefficients for " + std::to_string(texels) +
                " texels x " + std::to_string(terms) + " terms x " + std::to_string(channels) + " channels");
  // Texels of each cluster, in texel order.
  std::vector<std::vector<std::size_t>> members(clusters);
  for (std::size_t t = 0; t < texels; ++t) {
    const std::int32_t id = ids[t];
    if (id < 0 || id >= clusters) throw Error("modulation: texel " + std::to_string(t) + " has an invalid cluster id");
    members[id].push_back(t);
  }
  std::vector<double> column, original;
  for (const auto& texelsOf : members) {
    const std::size_t n = texelsOf.size();
    if (!n) continue;
    // Each channel's columns (term r at r x channels + c) apart: channel c's values mix only them.
    for (int c = 0; c < channels; ++c) {
      std::vector<std::vector<double>> basis;  // orthonormal columns so far (unit norm)
      for (int r = 0; r < terms; ++r) {
        const std::size_t col = static_cast<std::size_t>(r) * channels + c;
        column.resize(n);
        for (std::size_t j = 0; j < n; ++j) column[j] = a[texelsOf[j] * columns + col];
        double before = 0;
        for (double v : column) before += v * v;
        for (const auto& q : basis) {  // modified Gram-Schmidt
          double dot = 0;
          for (std::size_t j = 0; j < n; ++j) dot += q[j] * column[j];
          for (std::size_t j = 0; j < n; ++j) column[j] -= dot * q[j];
        }
        double norm = 0;
        for (double v : column) norm += v * v;
        // A column (nearly) inside the span of the earlier ones carries nothing new: drop it.
        const bool degenerate = !(norm > 1e-10 * std::max(before, 1e-30)) || !(norm > 0);
        const double unit = degenerate ? 0.0 : 1.0 / std::sqrt(norm);
        for (double& v : column) v *= unit;
        for (std::size_t j = 0; j < n; ++j)
          a[texelsOf[j] * columns + col] = static_cast<float>(column[j] * std::sqrt(static_cast<double>(n)));
        if (!degenerate) basis.push_back(column);
      }
    }
  }
  return a;
}

std::string modulationDescription(const TexelModulation& m) {
  return std::to_string(m.terms) + " RGB term" + (m.terms > 1 ? "s" : "") +
         " per cluster, mixed by per-texel coefficients (" + (m.channels > 1 ? "one per channel, " : "") +
         (m.decorrelated ? "decorrelated " : "") + std::to_string(m.bits) + "-bit codes)";
}

std::vector<float> dequantizeTexelCoefficients(const TexelModulation& m) {
  std::vector<float> a(m.codes.size());
  const std::size_t columns = static_cast<std::size_t>(std::max(m.columns(), 1));
  for (std::size_t i = 0; i < a.size(); ++i) a[i] = dequantizeTexelCoefficient(m, static_cast<int>(i % columns), m.codes[i]);
  if (!m.decorrelated) return a;
  // x_c = sum_k R[c][k] y_k per term; in double (float products are exact there), so that no
  // compiler's contraction into fused multiply-adds changes the result.
  for (std::size_t t = 0; t < a.size() / columns; ++t)
    for (int r = 0; r < m.terms; ++r) {
      float* x = &a[t * columns + 3 * r];
      const float y[3] = {x[0], x[1], x[2]};
      for (int c = 0; c < 3; ++c) {
        double v = 0;
        for (int k = 0; k < 3; ++k) v += static_cast<double>(m.rotation[9 * r + 3 * c + k]) * y[k];
        x[c] = static_cast<float>(v);
      }
    }
  return a;
}

}  // namespace nbtf
