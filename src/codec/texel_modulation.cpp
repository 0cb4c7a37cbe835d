#include "codec/texel_modulation.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "util/error.h"

namespace nbtf {

TexelModulation quantizeTexelCoefficients(const std::vector<float>& coefficients, int terms, int bits, int channels) {
  if (terms < 1 || terms > kMaxModulationTerms)
    throw Error("modulation terms must be in 1.." + std::to_string(kMaxModulationTerms) + ", got " +
                std::to_string(terms));
  if (bits < 1 || bits > 16) throw Error("modulation bits must be in 1..16, got " + std::to_string(bits));
  if (channels != 1 && channels != 3) throw Error("modulation channels must be 1 or 3, got " + std::to_string(channels));
  const int columns = terms * channels;
  if (coefficients.empty() || coefficients.size() % columns)
    throw Error("modulation: " + std::to_string(coefficients.size()) + " coefficients for " + std::to_string(terms) +
                " terms x " + std::to_string(channels) + " channels");
  const std::size_t texels = coefficients.size() / columns;
  TexelModulation m;
  m.terms = terms;
  m.channels = channels;
  m.bits = bits;
  m.codes.resize(coefficients.size());
  const double levels = static_cast<double>((1u << bits) - 1);
  std::vector<float> column(texels);
  for (int r = 0; r < columns; ++r) {
    for (std::size_t t = 0; t < texels; ++t) {
      column[t] = coefficients[t * columns + r];
      if (!std::isfinite(column[t]))
        throw Error("modulation: texel " + std::to_string(t) + " has a non-finite coefficient in term " +
                    std::to_string(r / channels));
    }
    // The range: from the 0.1% to the 99.9% quantile (min and max below 1000 texels), so that a
    // few outlying texels do not coarsen the steps for all others; those few are clamped.
    const std::size_t cut = texels >= 1000 ? texels / 1000 : 0;
    std::nth_element(column.begin(), column.begin() + cut, column.end());
    const float lo = column[cut];
    std::nth_element(column.begin(), column.begin() + (texels - 1 - cut), column.end());
    const float hi = column[texels - 1 - cut];
    m.minimum[r] = lo;
    m.maximum[r] = hi;
    const double span = static_cast<double>(hi) - lo;
    for (std::size_t t = 0; t < texels; ++t) {
      double q = span > 0 ? std::round((coefficients[t * columns + r] - static_cast<double>(lo)) / span * levels) : 0.0;
      m.codes[t * columns + r] = static_cast<std::uint16_t>(std::clamp(q, 0.0, levels));
    }
  }
  return m;
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
         std::to_string(m.bits) + "-bit codes)";
}

std::vector<float> dequantizeTexelCoefficients(const TexelModulation& m) {
  std::vector<float> a(m.codes.size());
  const std::size_t columns = static_cast<std::size_t>(std::max(m.columns(), 1));
  for (std::size_t i = 0; i < a.size(); ++i) a[i] = dequantizeTexelCoefficient(m, static_cast<int>(i % columns), m.codes[i]);
  return a;
}

}  // namespace nbtf
