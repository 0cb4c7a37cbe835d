#include "preprocess/abrdf_source.h"

#include <algorithm>
#include <numeric>

#include "io/color.h"
#include "util/error.h"
#include "util/page_buffer.h"
#include "util/parallel.h"
#include "util/progress.h"

namespace nbtf {

namespace {

// SIMD alignment of Eigen's vectorized code in this build, in floats (X's start is aligned to it).
constexpr Eigen::Index kAlign = 16 / sizeof(float);

// One buffer per worker thread, allocated on first use, in pages of its own (util/page_buffer.h:
// a slice of 128 MiB faults in 2 MiB at a time where huge pages are granted).
struct WorkerBuffers {
  explicit WorkerBuffers(int workers) : buffers(workers) {}
  float* get(int worker, Eigen::Index size) {
    PageBuffer& b = buffers[worker];
    const std::size_t bytes = static_cast<std::size_t>(size) * sizeof(float);
    if (b.size() < bytes) b = PageBuffer(bytes);
    return reinterpret_cast<float*>(b.data());
  }
  std::vector<PageBuffer> buffers;
};

}  // namespace

Eigen::Index columnSliceWidth(Eigen::Index rows) {
  constexpr Eigen::Index kMaxFloats = (Eigen::Index(256) << 20) / sizeof(float);
  if (rows <= 0 || rows * kColumnSlice <= kMaxFloats) return kColumnSlice;
  return std::max<Eigen::Index>(16, (kMaxFloats / rows) / 16 * 16);
}

void AbrdfSource::forEachColumnSlice(const ColumnVisit& visit, const std::string& label) const {
  const Eigen::Index m = rows(), d = cols(), width = columnSliceWidth(m);
  const Eigen::Index slices = (d + width - 1) / width;
  const float* x = dense();
  WorkerBuffers buffers(x ? 0 : threadCount());
  Progress bar(label, static_cast<std::size_t>(d), !label.empty());
  parallelForDynamic(static_cast<std::size_t>(slices), [&](std::size_t s, int worker) {
    const Eigen::Index c0 = static_cast<Eigen::Index>(s) * width, c1 = std::min(d, c0 + width);
    if (x) {
      visit(c0, c1, x + c0 * m);
    } else {
      // Column c at the offset modulo the SIMD width that it has in X.
      float* data = buffers.get(worker, m * width + kAlign) + (c0 * m) % kAlign;
      fillColumns(c0, c1, data);
      visit(c0, c1, data);
    }
    bar.advance(static_cast<std::size_t>(c1 - c0));
  });
  bar.finish();
}

void AbrdfSource::forEachRowSlice(const RowVisit& visit, const std::string& label) const {
  const Eigen::Index m = rows(), d = cols();
  const Eigen::Index slices = (m + kRowSlice - 1) / kRowSlice;
  const float* x = dense();
  WorkerBuffers buffers(x ? 0 : threadCount());
  Progress bar(label, static_cast<std::size_t>(m), !label.empty());
  parallelForDynamic(static_cast<std::size_t>(slices), [&](std::size_t s, int worker) {
    const Eigen::Index r0 = static_cast<Eigen::Index>(s) * kRowSlice, r1 = std::min(m, r0 + kRowSlice);
    if (x) {
      visit(r0, r1, x + r0, m);
    } else {
      float* data = buffers.get(worker, kRowSlice * d);
      fillRows(r0, r1, data);
      visit(r0, r1, data, r1 - r0);
    }
    bar.advance(static_cast<std::size_t>(r1 - r0));
  });
  bar.finish();
}

MatrixXfCol AbrdfSource::gatherRows(const std::vector<Eigen::Index>& texels, const std::string& label) const {
  const Eigen::Index count = static_cast<Eigen::Index>(texels.size());
  for (Eigen::Index k = 0; k < count; ++k)
    if (texels[k] < 0 || texels[k] >= rows() || (k > 0 && texels[k] <= texels[k - 1]))
      throw Error("ABRDF source: texel " + std::to_string(texels[k]) + " at position " + std::to_string(k) +
                  " is out of order or outside [0, " + std::to_string(rows()) + ")");
  MatrixXfCol out(count, cols());
  // Runs of a few hundred texels: enough runs to keep every thread busy on a sample of 2,048.
  constexpr Eigen::Index kRun = 256;
  Progress bar(label, static_cast<std::size_t>(count), !label.empty());
  parallelForDynamic(static_cast<std::size_t>((count + kRun - 1) / kRun), [&](std::size_t run, int) {
    const Eigen::Index k0 = static_cast<Eigen::Index>(run) * kRun, n = std::min(kRun, count - k0);
    fillTexels(texels.data() + k0, n, out.data() + k0, count);
    bar.advance(static_cast<std::size_t>(n));
  });
  bar.finish();
  return out;
}

void AbrdfSource::fillColumns(Eigen::Index c0, Eigen::Index c1, float* out) const {
  const float* x = dense();
  if (!x) throw Error("ABRDF source: no column data");
  std::copy(x + c0 * rows(), x + c1 * rows(), out);
}

void AbrdfSource::fillRows(Eigen::Index r0, Eigen::Index r1, float* out) const {
  const float* x = dense();
  if (!x) throw Error("ABRDF source: no row data");
  for (Eigen::Index d = 0; d < cols(); ++d) std::copy(x + d * rows() + r0, x + d * rows() + r1, out + d * (r1 - r0));
}

void AbrdfSource::fillTexels(const Eigen::Index* texels, Eigen::Index n, float* out, Eigen::Index ld) const {
  const float* x = dense();
  if (!x) throw Error("ABRDF source: no row data");
  for (Eigen::Index d = 0; d < cols(); ++d)
    for (Eigen::Index k = 0; k < n; ++k) out[d * ld + k] = x[d * rows() + texels[k]];
}

// ---- From the stack

StackAbrdfSource::StackAbrdfSource(const BtfStack& stack, Standardization standardization, ColumnMoments moments)
    : stack_(stack), s_(std::move(standardization)), moments_(std::move(moments)) {
  const Eigen::Index d = cols();
  if (s_.mean.size() != d || s_.stddev.size() != d)
    throw Error("ABRDF source: the standardization has " + std::to_string(s_.mean.size()) + " dimensions, the stack " +
                std::to_string(d));
  if (stack_.sampleType() != SampleType::Srgb8) return;
  // log(x + 1) of the 256 linear values, through the same function X is transformed with, then
  // standardized with the arithmetic of Standardization::apply: the value X holds for each byte.
  const std::vector<float> logs = log1pOfSrgb8();
  table_.resize(static_cast<std::size_t>(d) * 256);
  parallelFor(static_cast<std::size_t>(d), [&](std::size_t begin, std::size_t end) {
    for (std::size_t j = begin; j < end; ++j) {
      float* t = &table_[j * 256];
      if (s_.stddev[j] > 0) {
        auto out = Eigen::Map<Eigen::ArrayXf>(t, 256);
        out = (Eigen::Map<const Eigen::ArrayXf>(logs.data(), 256) - s_.mean[j]) * (1.0f / s_.stddev[j]);
      } else {
        std::fill(t, t + 256, 0.0f);
      }
    }
  });
}

StackAbrdfSource::StackAbrdfSource(const BtfStack& stack, float alpha) : stack_(stack), alpha_(alpha) {
  if (!(alpha > 0)) throw Error("ABRDF source: alpha must be > 0, got " + std::to_string(alpha));
  if (stack_.sampleType() != SampleType::Srgb8) return;
  const float* linear = srgb8ToLinearTable();
  table_.resize(256);
  for (int b = 0; b < 256; ++b) table_[b] = linear[b] / alpha;
}

StackAbrdfSource StackAbrdfSource::linear(const BtfStack& stack, float alpha) { return StackAbrdfSource(stack, alpha); }

bool StackAbrdfSource::forEachCodedImage(const CodedImageVisit& visit, const std::string& label) const {
  // The coded images carry one table per column: the standardized log source's layout.
  if (table_.empty() || isLinear()) return false;
  std::vector<std::vector<std::uint8_t>> copies(threadCount());  // images read out of a scratch file
  Progress bar(label, static_cast<std::size_t>(cols()), !label.empty());
  parallelForDynamic(static_cast<std::size_t>(stack_.numImages()), [&](std::size_t image, int worker) {
    const std::uint8_t* bytes = stack_.readImageBytes(static_cast<int>(image), 0, stack_.bytesPerImage(), copies[worker]);
    visit(static_cast<Eigen::Index>(image), bytes, &table_[image * 3 * 256], worker);
    bar.advance(3);
  });
  bar.finish();
  return true;
}

std::size_t StackAbrdfSource::workingBytes(std::int64_t texels, int images, SampleType type, int workers) {
  const std::size_t d = 3 * static_cast<std::size_t>(images), m = static_cast<std::size_t>(texels);
  const std::size_t tables = type == SampleType::Srgb8 ? d * 256 * sizeof(float) : 0;
  const std::size_t column = (m * static_cast<std::size_t>(columnSliceWidth(texels)) + kAlign) * sizeof(float);
  const std::size_t row = static_cast<std::size_t>(kRowSlice) * d * sizeof(float);
  const std::size_t image = type == SampleType::Srgb8 ? 0 : m * 3 * sizeof(float);
  return tables + static_cast<std::size_t>(std::max(1, workers)) * (column + row + image);
}

std::size_t StackAbrdfSource::sliceBytes(int workers) const {
  return workingBytes(stack_.numTexels(), stack_.numImages(), stack_.sampleType(), workers);
}

// A half stack: linear values -> log(x + 1) -> standardized, as Standardization::apply does;
// or, for the linear source, divided by alpha.
void StackAbrdfSource::transformRun(float* values, Eigen::Index n, Eigen::Index d) const {
  auto v = Eigen::Map<Eigen::ArrayXf>(values, n);
  if (isLinear()) {
    v /= alpha_;
  } else if (s_.stddev[d] > 0) {
    log1pRun(values, n);
    v = (v - s_.mean[d]) * (1.0f / s_.stddev[d]);
  } else {
    v = 0.0f;
  }
}

void StackAbrdfSource::fillColumns(Eigen::Index c0, Eigen::Index c1, float* out) const {
  const Eigen::Index m = rows();
  const bool srgb = stack_.sampleType() == SampleType::Srgb8;
  std::vector<float> rgb(srgb ? 0 : static_cast<std::size_t>(m) * 3);  // half or computed: one linear image
  std::vector<std::uint8_t> copy;  // an 8-bit image read out of a scratch file
  for (Eigen::Index image = c0 / 3; image <= (c1 - 1) / 3; ++image) {
    const std::uint8_t* bytes =
        srgb ? stack_.readImageBytes(static_cast<int>(image), 0, stack_.bytesPerImage(), copy) : nullptr;
    if (!srgb) stack_.imageLinear(static_cast<int>(image), rgb.data());
    for (int c = 0; c < 3; ++c) {
      const Eigen::Index d = 3 * image + c;
      if (d < c0 || d >= c1) continue;
      float* column = out + (d - c0) * m;
      if (srgb) {
        const float* t = table(d);
        for (Eigen::Index i = 0; i < m; ++i) column[i] = t[bytes[3 * i + c]];
      } else {
        for (Eigen::Index i = 0; i < m; ++i) column[i] = rgb[3 * i + c];
        transformRun(column, m, d);
      }
    }
  }
}

void StackAbrdfSource::fillRows(Eigen::Index r0, Eigen::Index r1, float* out) const {
  std::vector<Eigen::Index> texels(static_cast<std::size_t>(r1 - r0));
  std::iota(texels.begin(), texels.end(), r0);
  fillTexels(texels.data(), r1 - r0, out, r1 - r0);
}

void StackAbrdfSource::fillTexels(const Eigen::Index* texels, Eigen::Index n, float* out, Eigen::Index ld) const {
  if (n == 0) return;
  if (stack_.sampleType() != SampleType::Srgb8) {
    // Half or computed: these texels' linear values (computed for them alone), then this
    // source's values per dimension.
    const std::vector<int> ids(texels, texels + n);
    std::vector<float> linear(ld == n ? 0 : static_cast<std::size_t>(n) * cols());  // out itself when dense
    stack_.gatherLinear(nullptr, 0, ids.data(), static_cast<int>(n), ld == n ? out : linear.data());
    for (Eigen::Index d = 0; d < cols(); ++d) {
      if (ld != n) std::copy_n(linear.data() + d * n, n, out + d * ld);
      transformRun(out + d * ld, n, d);
    }
    return;
  }
  // 8-bit: of each image the bytes from the first texel to the last, read out of a scratch
  // file rather than mapped (a pass over a large stack through the mapping maps it again
  // fault by fault).
  const Eigen::Index first = texels[0];
  const std::size_t span = 3 * static_cast<std::size_t>(texels[n - 1] - first + 1);
  const bool contiguous = texels[n - 1] - first == n - 1;
  std::vector<std::uint8_t> copy;
  for (int image = 0; image < stack_.numImages(); ++image) {
    const std::uint8_t* bytes = stack_.readImageBytes(image, 3 * static_cast<std::size_t>(first), span, copy);
    for (int c = 0; c < 3; ++c) {
      const Eigen::Index d = 3 * static_cast<Eigen::Index>(image) + c;
      const float* t = table(d);
      float* column = out + d * ld;
      if (contiguous)  // a row slice: no index to load per value (the projection pass's loop)
        for (Eigen::Index k = 0; k < n; ++k) column[k] = t[bytes[3 * k + c]];
      else
        for (Eigen::Index k = 0; k < n; ++k) column[k] = t[bytes[3 * (texels[k] - first) + c]];
    }
  }
}

}  // namespace nbtf
